//! A stand-in for the two vendor haptic libraries dynaclay loads at run time: the subset of
//! OpenHaptics' HD API (`libHD.so`) and of Force Dimension's DHD API (`libdhd.so`) that the
//! drivers call, exported with the same C names and signatures, behind one simulated arm.
//!
//! Built as `libdynaclay_vendor_standin.so`; point `DYNACLAY_HD_LIB` or `DYNACLAY_DHD_LIB` at it
//! (or give its path to the driver) and `--device touch` or `--device dhd` open it as if it
//! were the vendor's library. It is test infrastructure, not a driver: state lives in one
//! process-wide record behind a mutex, and every call is counted so tests can check what the
//! driver did (how many force commands per servo tick, the last force, whether force output
//! was enabled).
//!
//! The arm's position stays put or moves along a straight line by a fixed step per servo tick
//! (HD) or per position read (DHD), as the test scripts it. HD's scheduler runs a servo thread
//! at 1 kHz unless manual mode is on; in manual mode nothing moves until the test calls
//! `standin_hd_tick(n)`, which runs the scheduled callbacks `n` times on the caller's thread,
//! so tests never depend on wall-clock rates.
//!
//! Numeric constants are the public header values (OpenHaptics `hdDefines.h`,
//! `hdScheduler.h`; Force Dimension `dhdc.h`).

pub mod dhd;
pub mod hd;

pub use dhd::DhdCalls;
pub use hd::HdCalls;
