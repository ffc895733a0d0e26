//! Measurements a person takes on a hand surface: the caliper dimensions of the seed paper's
//! Table 1 (subject-format spec, section 1) read off a skin by their definitions, from the
//! surface, the joints and the landmarks, never from template vertex pairs, so any closed skin
//! (a fitted skin, a true skin, a CT-like surface, a procedural body) can be measured.

pub mod caliper;
pub mod landmarks;

pub use caliper::{measure_dimensions, Measured};
pub use landmarks::landmarks_on_skin;
