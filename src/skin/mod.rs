//! The subject's skin in the reference posture (seed paper section 3.5): the simplified
//! template fitted to the subject's landmarks and caliper dimensions.

pub mod correspondence;
