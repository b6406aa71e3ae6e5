//! (engine: in progress)
