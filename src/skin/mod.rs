//! The skin surface of an individual hand (seed paper section 3.5): carrying the landmark-fitted
//! deformation of the simplified template over to the high-resolution one.

pub mod transfer;
