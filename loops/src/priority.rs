//! Real-time scheduling and core pinning for the calling thread, reported as values.
//!
//! Guarantee: these functions never panic and never fail a loop. Asking for SCHED_FIFO returns
//! an [`RtOutcome`] saying what the OS granted (or why not, with a hint how to allow it); pinning
//! returns a [`PinOutcome`]. Both are plain `Copy` data so a loop can publish them without
//! allocating. Call them once, from the thread to change, before its loop starts: they make
//! system calls and [`pin_current_thread`] allocates (it lists the cores).

use std::fmt;

use serde::{Deserialize, Serialize};

/// Default SCHED_FIFO priority for the haptic loop: above the kernel's threaded interrupt
/// handlers (50) so device I/O completion cannot preempt it, below the watchdog/migration
/// threads (99).
pub const DEFAULT_RT_PRIORITY: i32 = 80;

/// What the OS did with a request for real-time (SCHED_FIFO) scheduling.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum RtOutcome {
    /// The loop did not ask (normal time-sharing priority).
    NotRequested,
    /// The thread now runs under SCHED_FIFO at `priority`.
    Granted {
        /// The SCHED_FIFO priority now in force.
        priority: i32,
    },
    /// The OS refused; `os_error` is the error number (`EPERM` = 1 without privilege).
    Denied {
        /// The priority that was asked for.
        priority: i32,
        /// Raw OS error number returned by `pthread_setschedparam`.
        os_error: i32,
    },
    /// The priority lies outside the range the OS allows for SCHED_FIFO.
    InvalidPriority {
        /// The priority that was asked for.
        priority: i32,
        /// Lowest SCHED_FIFO priority on this system.
        min: i32,
        /// Highest SCHED_FIFO priority on this system.
        max: i32,
    },
    /// This platform has no SCHED_FIFO.
    Unsupported,
}

impl RtOutcome {
    /// True if the thread runs at real-time priority.
    #[must_use]
    pub fn is_granted(&self) -> bool {
        matches!(self, Self::Granted { .. })
    }

    /// How to obtain real-time priority, for outcomes where it was asked for and refused.
    #[must_use]
    pub fn hint(&self) -> Option<&'static str> {
        match self {
            Self::Denied { .. } => Some(
                "run as root, grant CAP_SYS_NICE (setcap cap_sys_nice+ep <binary>), or set \
                 `<user> - rtprio 99` in /etc/security/limits.conf and log in again",
            ),
            Self::InvalidPriority { .. } => Some("choose a priority inside the SCHED_FIFO range"),
            _ => None,
        }
    }
}

impl fmt::Display for RtOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::NotRequested => write!(f, "normal priority (real-time not requested)"),
            Self::Granted { priority } => write!(f, "SCHED_FIFO priority {priority} granted"),
            Self::Denied { priority, os_error } => write!(
                f,
                "SCHED_FIFO priority {priority} denied: {}; {}",
                std::io::Error::from_raw_os_error(os_error),
                self.hint().unwrap_or_default()
            ),
            Self::InvalidPriority { priority, min, max } => write!(
                f,
                "SCHED_FIFO priority {priority} is outside the allowed range {min}..={max}"
            ),
            Self::Unsupported => write!(f, "SCHED_FIFO is not supported on this platform"),
        }
    }
}

/// Asks for SCHED_FIFO at `priority` for the calling thread and reports what happened.
///
/// Never panics; a refusal leaves the thread at its previous policy.
#[cfg(target_os = "linux")]
#[must_use = "the outcome says whether the thread really runs at real-time priority"]
pub fn request_realtime(priority: i32) -> RtOutcome {
    // SAFETY: both calls only read a constant policy id and have no preconditions.
    let (min, max) = unsafe {
        (
            libc::sched_get_priority_min(libc::SCHED_FIFO),
            libc::sched_get_priority_max(libc::SCHED_FIFO),
        )
    };
    if min < 0 || max < 0 {
        return RtOutcome::Unsupported;
    }
    if !(min..=max).contains(&priority) {
        return RtOutcome::InvalidPriority { priority, min, max };
    }
    // SAFETY: `sched_param` is a plain C struct of integers, for which all-zero is valid.
    let mut param: libc::sched_param = unsafe { std::mem::zeroed() };
    param.sched_priority = priority;
    // SAFETY: `pthread_self()` is always a live thread handle (the caller), and `param` is a
    // valid, initialised `sched_param` that outlives the call.
    let rc = unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
    if rc == 0 {
        RtOutcome::Granted { priority }
    } else {
        // NOTE: pthread functions return the error number instead of setting errno.
        RtOutcome::Denied {
            priority,
            os_error: rc,
        }
    }
}

/// Asks for SCHED_FIFO at `priority` for the calling thread and reports what happened.
#[cfg(not(target_os = "linux"))]
#[must_use = "the outcome says whether the thread really runs at real-time priority"]
pub fn request_realtime(_priority: i32) -> RtOutcome {
    RtOutcome::Unsupported
}

/// The calling thread's scheduling policy and priority as the OS reports them now, e.g.
/// `(libc::SCHED_FIFO, 80)`; `None` if the query fails or the platform is not Linux.
#[must_use]
pub fn current_schedule() -> Option<(i32, i32)> {
    #[cfg(target_os = "linux")]
    {
        let mut policy = 0;
        // SAFETY: all-zero is a valid `sched_param` (plain integers).
        let mut param: libc::sched_param = unsafe { std::mem::zeroed() };
        // SAFETY: `pthread_self()` is the live calling thread; both out-pointers are valid and
        // exclusively borrowed for the call.
        let rc =
            unsafe { libc::pthread_getschedparam(libc::pthread_self(), &mut policy, &mut param) };
        (rc == 0).then_some((policy, param.sched_priority))
    }
    #[cfg(not(target_os = "linux"))]
    {
        None
    }
}

/// What happened to a request to pin a loop thread to one core.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum PinOutcome {
    /// No pinning was asked for; the OS may move the thread.
    NotRequested,
    /// The thread now runs only on `core`.
    Pinned {
        /// The core id the thread is bound to.
        core: usize,
    },
    /// `core` is not one of the cores this process may use.
    NoSuchCore {
        /// The core that was asked for.
        core: usize,
        /// How many cores the process may use.
        available: usize,
    },
    /// The OS refused to set the affinity.
    Failed {
        /// The core that was asked for.
        core: usize,
    },
}

impl fmt::Display for PinOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::NotRequested => write!(f, "not pinned"),
            Self::Pinned { core } => write!(f, "pinned to core {core}"),
            Self::NoSuchCore { core, available } => {
                write!(
                    f,
                    "core {core} not available (this process may use {available} cores)"
                )
            }
            Self::Failed { core } => write!(f, "pinning to core {core} refused by the OS"),
        }
    }
}

/// Binds the calling thread to core `core` (an index into the cores this process may use).
/// Allocates (it lists the cores); call it before the loop starts.
#[must_use = "the outcome says whether the thread is really pinned"]
pub fn pin_current_thread(core: usize) -> PinOutcome {
    let cores = core_affinity::get_core_ids().unwrap_or_default();
    match cores.get(core) {
        None => PinOutcome::NoSuchCore {
            core,
            available: cores.len(),
        },
        Some(&id) if core_affinity::set_for_current(id) => PinOutcome::Pinned { core },
        Some(_) => PinOutcome::Failed { core },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn request_returns_an_outcome_either_way() {
        // Run on a fresh thread so the test runner's threads keep their policy.
        let (outcome, schedule) = std::thread::spawn(|| {
            let outcome = request_realtime(10);
            (outcome, current_schedule())
        })
        .join()
        .expect("priority thread");
        match outcome {
            RtOutcome::Granted { priority } => {
                assert_eq!(priority, 10);
                #[cfg(target_os = "linux")]
                assert_eq!(schedule, Some((libc::SCHED_FIFO, 10)));
            }
            RtOutcome::Denied { os_error, .. } => {
                assert_ne!(os_error, 0);
                assert!(outcome.to_string().contains("CAP_SYS_NICE"));
                #[cfg(target_os = "linux")]
                assert_ne!(schedule.map(|s| s.0), Some(libc::SCHED_FIFO));
            }
            RtOutcome::Unsupported => {}
            other => panic!("unexpected outcome {other:?}"),
        }
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn out_of_range_priority_is_reported_not_applied() {
        let outcome = std::thread::spawn(|| request_realtime(1000))
            .join()
            .expect("thread");
        assert!(matches!(
            outcome,
            RtOutcome::InvalidPriority { priority: 1000, .. }
        ));
        assert!(!outcome.is_granted());
        assert!(outcome.hint().is_some());
    }

    #[test]
    fn outcomes_round_trip_through_json() {
        for outcome in [
            RtOutcome::NotRequested,
            RtOutcome::Granted { priority: 80 },
            RtOutcome::Denied {
                priority: 80,
                os_error: 1,
            },
        ] {
            let json = serde_json::to_string(&outcome).expect("serialise");
            let back: RtOutcome = serde_json::from_str(&json).expect("parse");
            assert_eq!(back, outcome);
        }
        assert_eq!(
            serde_json::to_string(&RtOutcome::Granted { priority: 5 }).expect("serialise"),
            r#"{"status":"granted","priority":5}"#
        );
    }

    #[test]
    fn pinning_to_a_missing_core_is_reported() {
        let outcome = std::thread::spawn(|| pin_current_thread(usize::MAX))
            .join()
            .expect("thread");
        assert!(matches!(
            outcome,
            PinOutcome::NoSuchCore {
                core: usize::MAX,
                ..
            }
        ));
    }

    #[test]
    fn pinning_to_core_zero_works_where_affinity_is_supported() {
        let outcome = std::thread::spawn(|| pin_current_thread(0))
            .join()
            .expect("thread");
        assert!(
            matches!(
                outcome,
                PinOutcome::Pinned { core: 0 } | PinOutcome::Failed { core: 0 }
            ) || matches!(outcome, PinOutcome::NoSuchCore { available: 0, .. }),
            "{outcome:?}"
        );
    }
}
