//! The process's resident set from `/proc/self/status` (Linux): the peak since the last
//! reset (VmHWM, reset through `/proc/self/clear_refs`, Linux ≥ 4.0) and the current one.

/// Resets the peak resident set to the current one.
pub fn reset_peak() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// A `kB` line of `/proc/self/status`, in bytes; NaN when it cannot be read.
fn status_bytes(key: &str) -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(key))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb * 1024.0)
}

/// The peak resident set since the last reset, bytes.
#[must_use]
pub fn peak_bytes() -> f64 {
    status_bytes("VmHWM:")
}

/// The resident set now, bytes.
#[must_use]
pub fn resident_bytes() -> f64 {
    status_bytes("VmRSS:")
}
