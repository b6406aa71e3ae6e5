//! The memory budget of `render`, `run --png` and `import --mesh`: what a mesh or an image
//! would take is estimated before anything is allocated, and a job over the budget is refused
//! with exit 2 and a message saying what to lower.
//!
//! The default budget is half of the machine's physical memory (`MemTotal` in
//! `/proc/meminfo`, read through a size cap), or 4 GiB where that cannot be read;
//! `--memory-budget-mib N` sets it.

use std::fmt;
use std::path::Path;

/// Bytes one sampled brick of the mesher is taken to cost, meshed and drawn: its 9³ samples
/// (2.9 KiB), its triangles (about 4 KiB for a smooth surface through it) and the copies made
/// to draw them (chunk buffers, GPU vertex and index buffers and their staging). The unit
/// test `a_brick_costs_less_than_the_budget_allows` checks it against a meshed ball.
pub const MESH_BYTES_PER_BRICK: u64 = 16 << 10;

/// Bytes one pixel of an offscreen render is taken to cost: 4× multisampled colour and depth
/// (32 bytes), the resolved frame, the readback buffer, the image in memory and the PNG
/// encoder's rows (16 bytes). An 8192² image is 3 GiB by this count, what it was measured to
/// take on llvmpipe.
pub const IMAGE_BYTES_PER_PIXEL: u64 = 48;

/// Budget used when `/proc/meminfo` cannot be read.
pub const FALLBACK_BUDGET_BYTES: u64 = 4 << 30;

/// How much memory one command may plan to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryBudget {
    /// The budget, bytes.
    pub bytes: u64,
    /// Where it came from.
    pub source: BudgetSource,
}

/// Where a [`MemoryBudget`] came from (said in the refusal).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BudgetSource {
    /// `--memory-budget-mib`.
    Flag,
    /// Half of `MemTotal`, bytes.
    HalfOfMemory { mem_total_bytes: u64 },
    /// `/proc/meminfo` could not be read.
    Fallback,
}

/// A job refused before it allocated: `what` would need at least `needed_bytes`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "{what}{}; nothing was allocated. {hint}{}",
    NeedClause { needed_bytes: *needed_bytes, at_least: *at_least, budget: *budget },
    if needed_bytes.is_some() { ", or raise --memory-budget-mib" } else { "" }
)]
pub struct OverBudget {
    /// What was refused ("meshing the clay at 4 cells per span", "a 16384×16384 image").
    pub what: String,
    /// The estimate (a lower bound when the count was stopped at the budget); `None` when
    /// the job is past what the mesher can address at all (`what` says why).
    pub needed_bytes: Option<u64>,
    /// Whether `needed_bytes` is only a lower bound.
    pub at_least: bool,
    /// The budget it passed.
    pub budget: MemoryBudget,
    /// What to lower (a sentence without its full stop).
    pub hint: &'static str,
}

impl MemoryBudget {
    /// The budget `--memory-budget-mib` asks for, else the machine's default.
    #[must_use]
    pub fn from_flag(mib: Option<u64>) -> Self {
        match mib {
            Some(m) => Self {
                bytes: m.saturating_mul(1 << 20),
                source: BudgetSource::Flag,
            },
            None => Self::machine_default(),
        }
    }

    /// Half of `MemTotal`, or [`FALLBACK_BUDGET_BYTES`].
    #[must_use]
    pub fn machine_default() -> Self {
        match mem_total_bytes(Path::new("/proc/meminfo")) {
            Some(total) => Self {
                bytes: total / 2,
                source: BudgetSource::HalfOfMemory {
                    mem_total_bytes: total,
                },
            },
            None => Self {
                bytes: FALLBACK_BUDGET_BYTES,
                source: BudgetSource::Fallback,
            },
        }
    }

    /// Bricks the budget holds at [`MESH_BYTES_PER_BRICK`].
    #[must_use]
    pub fn bricks(&self) -> u64 {
        self.bytes / MESH_BYTES_PER_BRICK
    }

    /// Refuses a `width × height` offscreen image over the budget.
    ///
    /// # Errors
    /// [`OverBudget`] naming the size.
    pub fn check_image(&self, width: u32, height: u32) -> Result<(), OverBudget> {
        let needed = u64::from(width) * u64::from(height) * IMAGE_BYTES_PER_PIXEL;
        if needed <= self.bytes {
            return Ok(());
        }
        Err(OverBudget {
            what: format!("rendering a {width}×{height} image"),
            needed_bytes: Some(needed),
            at_least: false,
            budget: *self,
            hint: "Lower --width/--height",
        })
    }
}

impl MemoryBudget {
    /// Refuses to read an input file whose decoded form would not fit: `bytes_per_byte` bytes
    /// of memory per byte of the file (the bytes read plus what they decode to). A missing
    /// file passes, for the reader to report.
    ///
    /// # Errors
    /// [`OverBudget`] naming the file and its size.
    pub fn check_input(&self, path: &Path, bytes_per_byte: u64) -> Result<(), OverBudget> {
        let Ok(meta) = std::fs::metadata(path) else {
            return Ok(());
        };
        let needed = meta.len().saturating_mul(bytes_per_byte);
        if needed <= self.bytes {
            return Ok(());
        }
        Err(OverBudget {
            what: format!("reading {} ({})", path.display(), human_bytes(meta.len())),
            needed_bytes: Some(needed),
            at_least: false,
            budget: *self,
            hint: "Use a smaller session",
        })
    }
}

/// `MemTotal` from a meminfo file, bytes (the file is read through a 64 KiB cap).
#[must_use]
pub fn mem_total_bytes(meminfo: &Path) -> Option<u64> {
    let bytes = dynaclay_files::read_regular_file(meminfo, 64 << 10).ok()?;
    let text = std::str::from_utf8(&bytes).ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let mut words = line["MemTotal:".len()..].split_whitespace();
    let value: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => value.checked_mul(1024),
        None => Some(value),
        Some(_) => None,
    }
}

/// `1.5 GiB`, `300 MiB`, `12 KiB`.
#[must_use]
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [(u64, &str); 3] = [(1 << 30, "GiB"), (1 << 20, "MiB"), (1 << 10, "KiB")];
    for (size, name) in UNITS {
        if bytes >= size {
            return format!("{:.1} {name}", bytes as f64 / size as f64);
        }
    }
    format!("{bytes} bytes")
}

/// What an [`OverBudget`] job would need, against which budget: the part of its message
/// between `what` and "nothing was allocated".
struct NeedClause {
    needed_bytes: Option<u64>,
    at_least: bool,
    budget: MemoryBudget,
}

impl fmt::Display for NeedClause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Some(needed) = self.needed_bytes else {
            return f.write_str(", more than can be meshed");
        };
        let budget = human_bytes(self.budget.bytes);
        let whence = match self.budget.source {
            BudgetSource::Flag => "set by --memory-budget-mib".to_owned(),
            BudgetSource::HalfOfMemory { mem_total_bytes } => {
                format!("half of this machine's {}", human_bytes(mem_total_bytes))
            }
            BudgetSource::Fallback => "the default where /proc/meminfo cannot be read".to_owned(),
        };
        let need = if self.at_least {
            "more than".to_owned()
        } else {
            format!("{} of memory, over", human_bytes(needed))
        };
        write!(
            f,
            " would need {need} the memory budget of {budget} ({whence})"
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mem_total_is_read_in_kibibytes_and_bad_files_give_none() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("meminfo");
        std::fs::write(&p, "MemTotal:       24684092 kB\nMemFree: 1 kB\n").unwrap();
        assert_eq!(mem_total_bytes(&p), Some(24_684_092 * 1024));
        std::fs::write(&p, "MemFree: 1 kB\n").unwrap();
        assert_eq!(mem_total_bytes(&p), None);
        assert_eq!(mem_total_bytes(Path::new("/dev/zero")), None);
        assert!(MemoryBudget::machine_default().bytes > 0);
    }

    #[test]
    fn images_over_the_budget_are_refused_with_the_size_and_the_fix() {
        let b = MemoryBudget::from_flag(Some(1024));
        assert!(b.check_image(1024, 768).is_ok());
        let e = b.check_image(16384, 16384).unwrap_err();
        let m = e.to_string();
        assert!(m.contains("16384×16384"), "{m}");
        assert!(m.contains("12.0 GiB") && m.contains("1.0 GiB"), "{m}");
        assert!(m.contains("--memory-budget-mib"), "{m}");
    }

    #[test]
    fn an_input_that_would_not_fit_decoded_is_refused_and_a_missing_one_passes() {
        let dir = tempfile::tempdir().unwrap();
        let big = dir.path().join("big.dclay");
        std::fs::write(&big, vec![0u8; 600 << 10]).unwrap();
        let b = MemoryBudget::from_flag(Some(1));
        let e = b.check_input(&big, 2).unwrap_err();
        assert!(e.to_string().contains("big.dclay"), "{e}");
        assert!(b.check_input(&big, 1).is_ok());
        assert!(b.check_input(&dir.path().join("none"), 2).is_ok());
    }
}
