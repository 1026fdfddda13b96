//! The text scene format: one API call per line.
