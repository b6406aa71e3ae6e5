//! (render: in progress)
