//! Simulated reference arm (in progress).
