//! The file boundary of dynaclay: every output is written whole or not at all, and every
//! input is read through a size cap.
//!
//! Guarantee for outputs ([`write_atomic`], [`write_atomic_with`], [`AtomicFile`]): the bytes
//! go to a fresh temporary file in the target's folder, which is flushed, fsynced and renamed
//! over the target, then the folder is fsynced. A failure at any step (a full disk, a lost
//! mount, a kill) leaves the previous file at the target untouched and removes the temporary
//! file. Only a regular file is ever replaced: a symbolic link at the target is neither written
//! through nor replaced, and neither is a directory, device, FIFO or socket.
//!
//! Guarantee for inputs ([`read_regular_file`]): only a regular file is opened (a FIFO would
//! block and `/dev/zero` never ends), and a file longer than the caller's cap is refused before
//! any of it is read, so the memory a read takes is bounded by the cap.
//!
//! Binary inputs, once read, are decoded through one bounds-checked cursor ([`ByteCursor`]).
//!
//! Nothing here runs on a real-time path: these functions allocate and block on the disk.

pub mod bounded_read;
mod cursor;
mod write;

pub use bounded_read::{BoundedReadError, read_regular_file};
pub use cursor::{ByteCursor, ShortRead};
pub use write::{AtomicFile, WriteError, check_target, write_atomic, write_atomic_with};
