//! Geometry core: indexed triangle meshes in f64 millimetres, their topology, rigid and similarity
//! registration (Horn 1987), Loop subdivision, closest-point queries (AABB tree), plane
//! sections and shading normals split at creases.

pub mod closest_point;
pub mod convex_hull_6d;
pub mod crease_normals;
pub mod horn;
pub mod loop_subdivision;
pub mod marching_tetrahedra;
pub mod mesh;
pub mod min_norm_point;
pub mod plane_section;
pub mod sparse_cholesky;
pub mod tet_mesh;
pub mod topology;

pub use crease_normals::{crease_normals, CreaseSplit};
pub use horn::{absolute_orientation, Registration};
pub use mesh::TriMesh;
pub use plane_section::{plane_section, Plane, SectionLoop};
pub use topology::Topology;

/// 3D point in millimetres.
pub type Point = nalgebra::Point3<f64>;
/// 3D vector in millimetres (or unitless for directions).
pub type Vec3 = nalgebra::Vector3<f64>;
