//! Safety filter between the engine and every device (in progress).
