//! Synthetic subjects: simulated measurements of a known hand, for validation.

pub mod voxel_scan;
