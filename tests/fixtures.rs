//! Shared fixtures of the cross-crate tests: models built through the whole chain
//! laminate → section → fem → mbs.
