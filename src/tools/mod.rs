//! (tools: in progress)
