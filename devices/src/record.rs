//! Record and replay of device sessions (in progress).
