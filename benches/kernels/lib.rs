//! Nothing: this package only holds the criterion bench `kernels.rs`.
