//! The `dynaclay` binary run as a user runs it, for the command-line tests: in a folder, with
//! arguments, and its refusals checked (exit 2, the message naming what and where). Shared
//! by `#[path]` (this folder is not a test target of its own).
// Each test target uses the helpers it needs.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

use dynaclay::field::BSplineLattice;
use dynaclay::io::{Session, save_session};
use dynaclay::tools::Clay;

/// The binary under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

/// Runs `dynaclay` with `args` in `dir`.
pub fn dynaclay(dir: &Path, args: &[&str]) -> Output {
    Command::new(BIN)
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

/// The command's stderr as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Asserts an input error: exit 2, the message naming each of `names`; returns it.
pub fn refused(out: &Output, names: &[&str]) -> String {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(2), "stderr: {err}");
    for n in names {
        assert!(err.contains(n), "{n} not in: {err}");
    }
    err
}

/// Saves a session whose clay is `clay` (every other part the default's) at `path`.
pub fn save_clay(path: &Path, clay: Clay) {
    let session = Session {
        clay,
        ..Session::default()
    };
    save_session(path, &session).unwrap();
}

/// A clay of one zero lattice of `dims` (spacing 0.1, at the origin).
pub fn zero_clay(dims: [usize; 3]) -> Clay {
    Clay::single(BSplineLattice::zeros(dims, 0.1, glam::Vec3::ZERO).unwrap())
}
