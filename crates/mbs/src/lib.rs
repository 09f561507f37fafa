//! Rigid–flexible multibody dynamics and the BDF integrator (placeholder; filled by a later issue).
