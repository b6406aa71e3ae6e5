//! (io: in progress)
