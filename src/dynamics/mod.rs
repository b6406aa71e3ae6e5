//! (dynamics: in progress)
