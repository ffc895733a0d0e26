//! Mesh file formats. Every reader takes the file's length unit explicitly and returns
//! millimetres; every writer writes to a temporary file and renames it (see [`atomic`]).

pub mod atomic;
pub mod fingerprint;
pub mod gltf;
pub mod gmsh;
pub mod obj;
pub mod output_paths;
pub mod ply;
pub mod stl;
pub mod units;
pub mod vtk;

pub use units::Units;
