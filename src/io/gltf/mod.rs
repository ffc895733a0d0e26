//! glTF 2.0 (Khronos, <https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html>): a reader for
//! `.gltf` (JSON with external or `data:` buffers) and `.glb` (binary container), and a GLB
//! writer, both carrying triangle meshes with optional normals, vertex colours and one skin.
//!
//! # Units
//! glTF lengths are metres (spec 3.4 "Coordinate System and Units"), but the caller names the
//! file's unit explicitly, as for every reader of this crate; the core works in millimetres.
//! Positions and every *translation* are multiplied by `units.to_mm()`. Rotations and node
//! scales are unitless and stay as they are; for a 4x4 matrix only the translation column is
//! scaled, which is the conjugation `S M S^-1` with `S = diag(s, s, s, 1)`, so products of
//! converted matrices equal the converted product (a world matrix converts like its locals).
//!
//! # What is read (see [`read_gltf`])
//! The nodes of the default scene (`scene`, else scene 0, else every parentless node) are walked
//! depth first in `children` order; every node with a mesh gives one [`SceneMesh`] named after
//! the node (else the mesh, else `mesh N`). All triangle primitives of that mesh are merged
//! into one [`TriMesh`] with offset indices, vertices as stored (never welded). Modes
//! TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN are read (strips and fans are expanded with the
//! winding of spec 3.7.2.1); POINTS and LINES-type primitives carry no surface
//! and are skipped (silently, since [`Scene`] has no place for warnings; a file in which nothing
//! is left is an error that lists what was skipped). Triangles that repeat a vertex index have
//! no area and are dropped. `NORMAL` is kept only when every triangle primitive of the mesh has
//! it; `COLOR_0` (RGB or RGBA, float or normalised integers) is kept when any has it, the others
//! count as white. A mesh shown by several nodes is read once per node; the total (vertices +
//! faces + joints) is capped at 4 per input byte plus 1 Mi so that instancing cannot blow a
//! small file up into a huge scene. Accessors of any component type are read (also
//! `KHR_mesh_quantization` data, normalised integers mapped per spec 3.11), including sparse
//! ones; geometry compression extensions (Draco, meshopt) are refused with a message.
//!
//! Skin weights: all `JOINTS_n`/`WEIGHTS_n` sets are merged per vertex (a joint named twice has
//! its weights summed), zero weights dropped, the 4 largest kept and renormalised.
//! [`SkinJoint::parent`] follows the node hierarchy only: the generic-hand assets keep their
//! joints as flat siblings, so there every parent is `None`.
//!
//! A node with a `skin` keeps its positions as stored: they are the bind pose, and the spec
//! (3.7.3 "Skins") ignores the mesh node's own transform for skinned meshes. Every other mesh
//! is placed by its node's world transform, normals by its inverse transpose, and its triangles
//! are reversed when that transform mirrors (spec 3.7.2.1: a negative determinant flips the
//! winding).
//!
//! # What is written (see [`write_glb`])
//! A single-buffer GLB that the Khronos glTF-Validator accepts without errors: one root node per
//! [`SceneMesh`], one shared PBR material, `u32` indices, `f32` attributes, and for a skin its
//! joint nodes, `inverseBindMatrices`, `JOINTS_0` (`u16`) and `WEIGHTS_0` (`f32`).
//!
//! Custom vertex attributes ([`VertexAttribute`], names starting with `_`, FLOAT SCALAR) and
//! morph targets ([`MorphTarget`]: a `POSITION` target with `min`/`max`, the mesh's default
//! `weights`, names in `mesh.extras.targetNames`) are written per mesh. The reader returns the
//! FLOAT SCALAR custom attributes that every triangle primitive of a mesh has (others, such as
//! vector or integer ones, are skipped), and the morph targets' `POSITION` displacements (zero
//! where a primitive's target has none; a target's normals and tangents are not read), default
//! weights (0 when the mesh has none) and names (`target N` without `targetNames`). An unskinned
//! mesh's displacements are turned by its node's world transform, like its normals' directions.
//!
//! # Animations (spec 3.11 "Animations")
//! A [`Scene`] may carry [`Animation`]s: channels that move the `translation` or `rotation` of a
//! mesh node or a skin joint ([`AnimationTarget`]) through keyframes interpolated LINEAR. Each
//! channel is written as one sampler whose input (times, seconds, with the `min`/`max` the spec
//! requires of sampler inputs) is shared by channels with the same times; translations are
//! converted like node translations, rotations written sign-continuous ([`sign_continuous`]).
//! The reader returns the LINEAR translation and rotation channels of the nodes it read and
//! skips the rest (scale, morph weights, STEP and CUBICSPLINE samplers).

mod animation;
mod buffer;
mod container;
mod read;
mod write;

#[cfg(test)]
mod tests;

use crate::error::{Error, Result};
use crate::geometry::{TriMesh, Vec3};
use crate::io::atomic::{read_bytes, write_bytes_atomic};
use crate::io::Units;
use nalgebra::{Matrix4, UnitQuaternion};
use std::path::Path;

/// One joint of a skin, in the rest (bind) pose.
#[derive(Clone, Debug, PartialEq)]
pub struct SkinJoint {
    /// The joint node's name (`node N` when the file gives none).
    pub name: String,
    /// Index into [`Skin::joints`] of the joint whose node is this node's parent in the file;
    /// `None` when the parent node is not a joint of this skin (or there is none).
    pub parent: Option<usize>,
    /// Rest local transform of the node (its TRS or matrix), translation in mm.
    pub local: Matrix4<f64>,
    /// Rest world transform (product of all ancestors' locals, joints or not), translation in mm.
    pub world: Matrix4<f64>,
    /// Inverse bind matrix, translation in mm (identity when the skin has none, spec 3.7.3).
    pub inverse_bind: Matrix4<f64>,
}

/// A skin: joints in the order the vertex joint indices refer to, and per-vertex weights.
#[derive(Clone, Debug, PartialEq)]
pub struct Skin {
    /// The skin's joints in `skins[i].joints` order.
    pub joints: Vec<SkinJoint>,
    /// Per vertex: up to 4 (joint index into `joints`, weight) with weight > 0, sorted by weight
    /// descending (ties by joint index), normalised to sum 1 (vertices with no weight get an
    /// empty Vec).
    pub weights: Vec<Vec<(usize, f64)>>,
}

/// One mesh instance of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneMesh {
    /// The node's name (the mesh's when the node has none).
    pub name: String,
    /// Geometry in mm.
    pub mesh: TriMesh,
    /// Unit vertex normals (`NORMAL`), one per vertex; zero where the file's normal was zero.
    pub normals: Option<Vec<Vec3>>,
    /// Linear RGBA per vertex (`COLOR_0`); alpha 1 when the file stores RGB.
    pub colors: Option<Vec<[f32; 4]>>,
    /// The node's skin with this mesh's weights.
    pub skin: Option<Skin>,
    /// Application-specific per-vertex scalars (glTF 2.0 spec 3.7.2.1: custom attribute names
    /// start with `_`), e.g. `_DISTANCE_MM`; a viewer can colour or probe the mesh by them.
    pub attributes: Vec<VertexAttribute>,
    /// Morph targets (spec 3.7.2.2): per-vertex displacements a viewer blends by weight.
    pub morph_targets: Vec<MorphTarget>,
}

/// A custom per-vertex attribute: one `f32` per vertex, stored as a FLOAT SCALAR accessor.
/// Values are stored as given (no unit conversion): the name should say the unit, as
/// `_DISTANCE_MM` does, because glTF has no place for it.
#[derive(Clone, Debug, PartialEq)]
pub struct VertexAttribute {
    /// The attribute semantic, starting with `_` (the writer refuses any other name, since
    /// the spec reserves the rest for its own semantics).
    pub name: String,
    /// One value per vertex.
    pub values: Vec<f32>,
}

/// One morph target of a mesh: a displacement per vertex (the spec's `POSITION` target)
/// and its default weight (the mesh's `weights`); the name goes to `mesh.extras.targetNames`,
/// the convention three.js and Blender read, since glTF itself names no target.
#[derive(Clone, Debug, PartialEq)]
pub struct MorphTarget {
    /// The target's name.
    pub name: String,
    /// One displacement per vertex, mm (converted to the file's unit like positions).
    pub displacements: Vec<Vec3>,
    /// The default weight: the shown shape is `position + Σ weight * displacement`.
    pub weight: f64,
}

/// The mesh instances of a glTF scene.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Scene {
    /// One entry per mesh node, in depth-first scene order.
    pub meshes: Vec<SceneMesh>,
    /// Keyframe animations of the mesh and joint nodes (glTF 2.0 spec 3.11 "Animations");
    /// empty for a still scene.
    pub animations: Vec<Animation>,
}

/// The node an animation channel moves: the node of a [`Scene::meshes`] entry, or a joint of
/// its skin.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AnimationTarget {
    /// The mesh node of `meshes[i]`. Its animated transform places the mesh's vertices as
    /// stored (for an unskinned mesh written by this crate the node has no other transform).
    /// A skinned mesh node cannot be a target: spec 3.7.3 ignores its transform.
    Mesh(usize),
    /// Joint `joint` (index into [`Skin::joints`]) of `meshes[mesh]`'s skin.
    Joint { mesh: usize, joint: usize },
}

/// The keyframe values of one channel, one per keyframe time. They replace the node's local
/// `translation` or `rotation` property (spec 3.11: animated TRS properties override the
/// node's own; the others keep their static value).
#[derive(Clone, Debug, PartialEq)]
pub enum Keyframes {
    /// Local translations, mm.
    Translation(Vec<Vec3>),
    /// Local rotations. The writer makes neighbours sign-continuous (see
    /// [`sign_continuous`]); the reader returns them as stored.
    Rotation(Vec<UnitQuaternion<f64>>),
}

impl Keyframes {
    /// Number of keyframes.
    pub fn len(&self) -> usize {
        match self {
            Keyframes::Translation(v) => v.len(),
            Keyframes::Rotation(v) => v.len(),
        }
    }

    /// No keyframe.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One animated property of one node, interpolated LINEAR (spec 3.11: lerp for translations,
/// slerp for rotations).
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// The node moved.
    pub target: AnimationTarget,
    /// Keyframe times, seconds, `>= 0` and strictly increasing (spec 3.11, sampler input).
    pub times: Vec<f64>,
    /// The values at those times.
    pub values: Keyframes,
}

/// A named set of channels played together (one glTF `animation`).
#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    pub name: String,
    pub channels: Vec<Channel>,
}

/// `quats` with each one's sign chosen so that its dot product with the previous one is not
/// negative. `q` and `-q` are the same rotation, but glTF's LINEAR rotation interpolation is a
/// slerp between the stored 4-vectors (spec 3.11 and Appendix "Interpolation"), which goes the
/// long way round (through up to 360 degrees) between neighbours of opposite signs; choosing
/// signs continuously makes every step the short way.
pub fn sign_continuous(quats: &[UnitQuaternion<f64>]) -> Vec<UnitQuaternion<f64>> {
    let mut out: Vec<UnitQuaternion<f64>> = Vec::with_capacity(quats.len());
    for q in quats {
        let q = match out.last() {
            Some(p) if p.coords.dot(&q.coords) < 0.0 => {
                UnitQuaternion::new_unchecked(-q.into_inner())
            }
            _ => *q,
        };
        out.push(q);
    }
    out
}

/// Read a `.gltf` (buffers external, relative to the file, or embedded as base64 `data:` URIs)
/// or `.glb` file whose lengths are in `units`; the result is in mm. The container is told
/// apart by its first bytes, not by the extension. See the [module documentation](self) for
/// which nodes and primitives are read and how transforms are applied.
///
/// Every count and offset is checked against the bytes present before anything is allocated;
/// a malformed file gives an [`Error::Input`] naming the file and the item (accessor, buffer
/// view, node, mesh, joint) at fault, never a panic.
pub fn read_gltf(path: &Path, units: Units) -> Result<Scene> {
    let bytes = read_bytes(path)?;
    let base = path.parent().unwrap_or_else(|| Path::new(""));
    guarded(path, || read::read_scene(&bytes, units, path, Some(base)))
}

/// [`read_gltf`] for bytes in memory: a GLB, or a glTF JSON whose buffers are embedded (`data:`
/// URIs); an external buffer URI is an error. `label` names the source in errors.
pub fn read_gltf_slice(bytes: &[u8], units: Units, label: &Path) -> Result<Scene> {
    guarded(label, || read::read_scene(bytes, units, label, None))
}

/// Write `scene` as a GLB file (atomically: temporary file, then rename) with lengths in
/// `units` (normally [`Units::Metres`], glTF's unit). See [`glb_bytes`].
pub fn write_glb(path: &Path, scene: &Scene, units: Units) -> Result<()> {
    let bytes = glb_bytes(scene, units).map_err(|e| e.in_file(path))?;
    write_bytes_atomic(path, &bytes)
}

/// The GLB bytes of `scene`, lengths in `units`.
///
/// Layout (glTF 2.0 spec 3.6 and 4.4): one buffer in the BIN chunk, one buffer view per
/// accessor at a 4-byte aligned offset, chunks padded (JSON with spaces, BIN with zeros).
/// Per [`SceneMesh`]: a root node without transform (the spec requires that of skinned mesh
/// nodes), `POSITION` with `min`/`max`, `NORMAL` if given (renormalised; a zero normal is
/// replaced by the mesh's angle-weighted vertex normal, else +Z, since the spec requires unit
/// normals), `COLOR_0` if given (`f32` RGBA clamped to [0, 1]), each custom attribute as a
/// FLOAT SCALAR accessor, morph targets as the primitive's `targets` (a `POSITION` accessor
/// each, with `min`/`max`) with the mesh's `weights` and `extras.targetNames`, `u32` indices.
/// A skin adds a
/// node per joint, nested by [`SkinJoint::parent`] with `local` as its transform (written as TRS
/// when the matrix decomposes, else as a matrix); a root joint whose `world` differs from its
/// `local` gets a parent node holding `world * local^-1`, so both read back unchanged. Weights
/// are written as the first 4 of each vertex, renormalised in `f32`.
///
/// Fails ([`Error::Invalid`], naming the mesh and item) on an empty mesh, attribute or weight
/// lists whose length is not the vertex count, a joint index or parent out of range, a cycle
/// of parents, a vertex of a skinned mesh without weight, more than 65536 joints, a non-finite
/// value, a joint whose `world` is not its parent's `world * local`, or a custom attribute
/// whose name does not start with `_` (or is given twice).
pub fn glb_bytes(scene: &Scene, units: Units) -> Result<Vec<u8>> {
    write::glb_bytes(scene, units)
}

/// Run a reader, turning a panic (which the checks are meant to make impossible) into an error
/// naming the file: the last-resort guard the task asks for around code we do not control.
fn guarded<T>(label: &Path, f: impl FnOnce() -> Result<T>) -> Result<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|_| {
        Err(Error::input(
            label,
            "the glTF reader failed unexpectedly on this file (internal error); please report it with the file",
        ))
    })
}
