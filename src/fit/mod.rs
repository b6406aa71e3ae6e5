//! (fit: in progress)
