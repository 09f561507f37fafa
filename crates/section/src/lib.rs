//! Finite-element cross-section analysis of composite beams (placeholder; filled by a later issue).
