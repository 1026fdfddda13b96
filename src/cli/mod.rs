//! The `primflow` command line.
