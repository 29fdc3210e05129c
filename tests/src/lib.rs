//! Cross-crate golden tests.
