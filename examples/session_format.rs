//! Rewrites a session file in another format version, timing the load and the save.
//!
//! The session is loaded and validated (any version from 1 to the current one), then written
//! atomically in the version asked for: the current one (bricked lattices) by default, or an
//! older one for a build that reads only those. Run with
//!
//! ```text
//! cargo run --release --example session_format -- IN.dclay OUT.dclay [VERSION]
//! ```
//!
//! `OUT.dclay` may replace only a session (the output rule every command follows). The
//! figures go to stderr: the file sizes, and the load and save times (wall clock, so a busy
//! machine shows in them).

use std::error::Error;
use std::path::PathBuf;
use std::time::Instant;

use dynaclay::io::{FORMAT_VERSION, check_replaceable, encode_version, load_session, write_atomic};

fn main() -> Result<(), Box<dyn Error>> {
    let mut args = std::env::args_os().skip(1);
    let usage = "usage: session_format IN.dclay OUT.dclay [VERSION]";
    let input = PathBuf::from(args.next().ok_or(usage)?);
    let output = PathBuf::from(args.next().ok_or(usage)?);
    let version = match args.next() {
        Some(v) => v.to_str().ok_or(usage)?.parse::<u32>()?,
        None => FORMAT_VERSION,
    };
    check_replaceable(&output)?;

    let started = Instant::now();
    let session = load_session(&input)?;
    let load_s = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let bytes = encode_version(&session, version)?;
    write_atomic(&output, &bytes)?;
    let save_s = started.elapsed().as_secs_f64();

    let in_bytes = std::fs::metadata(&input)?.len();
    eprintln!(
        "{}: {in_bytes} bytes, loaded in {load_s:.3} s; {}: {} bytes of format {version}, saved in {save_s:.3} s",
        input.display(),
        output.display(),
        bytes.len()
    );
    Ok(())
}
