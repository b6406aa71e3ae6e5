//! Fixed-rate loops, triple-buffer exchange and latency recording (no geometry).
