//! The skin stage of the seed paper (sections 3.5 and 3.6): the template surface made homologous
//! to the subject.
//!
//! * [`simplify`] reduces the high-resolution template to the ~1,000-face mesh the landmark fit
//!   runs on (Garland & Heckbert quadric error metrics, landmark vertices kept).
//! * [`correspondence`] fits that mesh to the subject's landmarks and caliper dimensions
//!   (Sumner & Popović's correspondence energy with the constraints of equation 2).
//! * [`transfer`] carries the fitted deformation back to the high-resolution template through
//!   per-face frames (equation 3).
//! * [`distal_frame`] aims each digit's last joint along its distal phalanx, carried from the
//!   template by homology (no joint beyond it says where the phalanx points).
//! * [`unfold`] relaxes the fitted displacement where it turns faces over (a skin never folds).
//! * [`shape_prior`] adds what the population says of the shape no landmark or caliper
//!   reaches (a normal-offset field predicted from the caliper dimensions).

pub mod correspondence;
pub mod distal_frame;
pub mod pipeline;
pub mod posture_fit;
pub mod section_centre;
pub mod section_scale;
pub mod shape_prior;
pub mod simplify;
pub mod transfer;
pub mod unfold;
