//! Cross-crate tests of the kestrel workspace live in `tests/`; this
//! library is intentionally empty of logic.
