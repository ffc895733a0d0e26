//! Motion-capture input: subject folders (`subject.toml`, spec section 1), C3D trials and the
//! marker trajectories every later stage shares.

pub mod c3d;
pub mod plausibility;
pub mod subject;
pub mod trajectories;
