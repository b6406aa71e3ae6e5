//! (mesh: in progress)
