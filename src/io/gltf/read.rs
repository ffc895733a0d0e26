//! The glTF reader: container, buffers, accessors, node hierarchy, skins and meshes, each
//! checked against the bytes present before use (see the parent module for the conventions).

use super::container::{data_uri, is_glb, percent_decode, split_glb, truncate};
use super::{
    Animation, AnimationTarget, Channel, Keyframes, MorphTarget, Scene, SceneMesh, Skin, SkinJoint,
    VertexAttribute,
};
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::io::Units;
use gltf_json as json;
use json::accessor::{ComponentType, Type};
use json::mesh::{Mode, Semantic};
use json::validation::Checked;
use nalgebra::{Matrix3, Matrix4, Quaternion, UnitQuaternion, Vector3};
use std::borrow::Cow;
use std::collections::hash_map::Entry;
use std::collections::HashMap;
use std::path::Path;

/// Required extensions that move geometry out of plain accessors, which this reader cannot
/// decode (any other required extension only concerns materials, textures, lights or, like
/// `KHR_mesh_quantization`, widens accessor types, which the generic accessor decoder handles).
const UNREADABLE_EXTENSIONS: &[&str] = &[
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
];

/// Elements (vertices + faces + joints) the scene may hold beyond 4 per input byte: room for
/// legitimate instancing of small meshes while a tiny file cannot make the reader build a
/// scene orders of magnitude larger than itself.
const INSTANCE_SLACK: usize = 1 << 20;

/// Parse a glTF or GLB held in `bytes` into a [`Scene`] in mm; `base` is the folder that
/// relative buffer URIs resolve against (`None`: external buffers are an error).
pub(super) fn read_scene(
    bytes: &[u8],
    units: Units,
    label: &Path,
    base: Option<&Path>,
) -> Result<Scene> {
    let err = |msg: String| Error::input(label, msg);
    let (json_text, bin) = if is_glb(bytes) {
        let glb = split_glb(bytes).map_err(err)?;
        (glb.json, glb.bin)
    } else {
        (bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes), None)
    };
    let root: json::Root = serde_json::from_slice(json_text)
        .map_err(|e| err(format!("glTF JSON is not valid: {e}")))?;
    if !root.asset.version.starts_with("2.") {
        return Err(err(format!(
            "asset.version is '{}'; only glTF 2.x is supported (convert glTF 1.0 files first)",
            truncate(&root.asset.version, 20)
        )));
    }
    if let Some(ext) = root
        .extensions_required
        .iter()
        .find(|e| UNREADABLE_EXTENSIONS.contains(&e.as_str()))
    {
        return Err(err(format!(
            "extensionsRequired names '{ext}': compressed geometry is not supported; decompress it first (e.g. gltf-transform copy)"
        )));
    }
    let (buffers, external_len) = load_buffers(&root, bin, label, base)?;
    let input_len = bytes.len() + external_len;
    let doc = Doc {
        root: &root,
        buffers,
        label,
        input_len,
        mm: units.to_mm(),
    };
    doc.scene()
}

/// The checked pieces of one document.
struct Doc<'a> {
    root: &'a json::Root,
    /// Buffer data, each cut to its declared `byteLength`.
    buffers: Vec<Cow<'a, [u8]>>,
    label: &'a Path,
    /// Bytes of all input (file plus external buffers): the cap for accessors without data
    /// and for instancing.
    input_len: usize,
    /// Millimetres per file unit.
    mm: f64,
}

/// The data of one accessor, decoded to f64 (normalised integers mapped to [0, 1] or [-1, 1]
/// as the table in spec 3.11 prescribes), `count * ncomp` values in element order.
struct AccessorData {
    values: Vec<f64>,
    count: usize,
    ncomp: usize,
    component: ComponentType,
}

/// Load every buffer: the GLB BIN chunk for a buffer without `uri` (spec 4.4.3.3 allows that
/// for buffer 0 only), a base64 `data:` URI, or a file relative to `base`. Each must hold at
/// least its `byteLength` bytes (the BIN chunk may be up to 3 bytes longer because of padding).
/// Also returns the bytes read from external files (the rest of the input is `bytes`).
fn load_buffers<'a>(
    root: &json::Root,
    bin: Option<&'a [u8]>,
    label: &Path,
    base: Option<&Path>,
) -> Result<(Vec<Cow<'a, [u8]>>, usize)> {
    let err = |msg: String| Error::input(label, msg);
    let mut out = Vec::with_capacity(root.buffers.len());
    let mut external_len = 0usize;
    for (i, b) in root.buffers.iter().enumerate() {
        let data: Cow<'a, [u8]> = match &b.uri {
            None => match (i, bin) {
                (0, Some(bin)) => Cow::Borrowed(bin),
                _ => {
                    return Err(err(format!(
                        "buffer {i} has no uri and is not the GLB BIN chunk (only buffer 0 of a .glb may omit it)"
                    )))
                }
            },
            Some(uri) => match data_uri(uri) {
                Some(decoded) => Cow::Owned(decoded.map_err(|m| err(format!("buffer {i}: {m}")))?),
                None => {
                    let Some(base) = base else {
                        return Err(err(format!(
                            "buffer {i} refers to the external file '{}', which cannot be resolved when reading from memory; read the file by path instead",
                            truncate(uri, 60)
                        )));
                    };
                    let rel = percent_decode(uri);
                    let has_scheme = rel
                        .split_once(':')
                        .is_some_and(|(s, _)| !s.contains('/') && s.len() > 1);
                    if has_scheme || Path::new(rel.as_ref()).is_absolute() {
                        return Err(err(format!(
                            "buffer {i}: uri '{}' is neither a data: URI nor a relative path",
                            truncate(uri, 60)
                        )));
                    }
                    let file = base.join(rel.as_ref());
                    let data = std::fs::read(&file).map_err(|e| {
                        err(format!("buffer {i}: cannot read '{}': {e}", file.display()))
                    })?;
                    external_len += data.len();
                    Cow::Owned(data)
                }
            },
        };
        let declared = b.byte_length.0;
        if declared > data.len() as u64 {
            return Err(err(format!(
                "buffer {i} declares {declared} bytes (byteLength), but only {} are present",
                data.len()
            )));
        }
        out.push(match data {
            Cow::Borrowed(d) => Cow::Borrowed(&d[..declared as usize]),
            Cow::Owned(mut d) => {
                d.truncate(declared as usize);
                Cow::Owned(d)
            }
        });
    }
    Ok((out, external_len))
}

/// Value of one component at `at` (bounds checked by the caller), normalised when asked:
/// spec 3.11 gives `max(c / 127, -1)`, `c / 255`, `max(c / 32767, -1)`, `c / 65535`.
fn component(bytes: &[u8], at: usize, ct: ComponentType, normalized: bool) -> f64 {
    let b = &bytes[at..at + ct.size()];
    match ct {
        ComponentType::I8 => {
            let v = f64::from(b[0] as i8);
            if normalized {
                (v / 127.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U8 => {
            let v = f64::from(b[0]);
            if normalized {
                v / 255.0
            } else {
                v
            }
        }
        ComponentType::I16 => {
            let v = f64::from(i16::from_le_bytes([b[0], b[1]]));
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U16 => {
            let v = f64::from(u16::from_le_bytes([b[0], b[1]]));
            if normalized {
                v / 65535.0
            } else {
                v
            }
        }
        ComponentType::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        ComponentType::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
    }
}

/// Byte offsets of the components of one element relative to its start, and the element's
/// byte size: matrix columns of 1- and 2-byte components are padded to 4 bytes (spec 3.6.2.4).
fn element_layout(ty: Type, ct: ComponentType) -> (Vec<usize>, usize) {
    let cs = ct.size();
    let cols = match ty {
        Type::Mat2 => 2,
        Type::Mat3 => 3,
        Type::Mat4 => 4,
        _ => {
            let n = ty.multiplicity();
            return ((0..n).map(|k| k * cs).collect(), n * cs);
        }
    };
    let col_bytes = (cols * cs).div_ceil(4) * 4;
    let offsets = (0..cols)
        .flat_map(|c| (0..cols).map(move |r| c * col_bytes + r * cs))
        .collect();
    (offsets, cols * col_bytes)
}

fn type_name(ty: Type) -> &'static str {
    match ty {
        Type::Scalar => "SCALAR",
        Type::Vec2 => "VEC2",
        Type::Vec3 => "VEC3",
        Type::Vec4 => "VEC4",
        Type::Mat2 => "MAT2",
        Type::Mat3 => "MAT3",
        Type::Mat4 => "MAT4",
    }
}

/// `name` as quoted in messages: `mesh 2 ('hand')` or `mesh 2`.
fn labelled(kind: &str, i: usize, name: Option<&str>) -> String {
    match name {
        Some(n) => format!("{kind} {i} ('{}')", truncate(n, 60)),
        None => format!("{kind} {i}"),
    }
}

impl Doc<'_> {
    fn err(&self, msg: String) -> Error {
        Error::input(self.label, msg)
    }

    /// The byte range `[start, start + len)` of buffer view `v` checked against its buffer.
    fn view_bytes(&self, v: usize, what: &str) -> Result<(&[u8], Option<usize>)> {
        let view = self.root.buffer_views.get(v).ok_or_else(|| {
            self.err(format!(
                "{what} names buffer view {v}, but the file has {}",
                self.root.buffer_views.len()
            ))
        })?;
        let b = view.buffer.value();
        let buf = self.buffers.get(b).ok_or_else(|| {
            self.err(format!(
                "buffer view {v} names buffer {b}, but the file has {}",
                self.buffers.len()
            ))
        })?;
        let off = view.byte_offset.map_or(0, |o| o.0);
        let len = view.byte_length.0;
        let end = off.checked_add(len).filter(|&e| e <= buf.len() as u64);
        let Some(end) = end else {
            return Err(self.err(format!(
                "buffer view {v} (bytes {off}..{off}+{len}) runs past the end of buffer {b} ({} bytes)",
                buf.len()
            )));
        };
        Ok((
            &buf[off as usize..end as usize],
            view.byte_stride.map(|s| s.0),
        ))
    }

    /// Decode accessor `a` (spec 3.6.2 "Accessors", including sparse storage, 3.6.2.3) after
    /// checking that every element lies inside its buffer view, so the allocation is bounded
    /// by the bytes present (an accessor without buffer view is capped by the input size).
    /// `what` says what the accessor is for, e.g. "JOINTS_0 of mesh 0 ('hand')".
    fn accessor(&self, a: usize, what: &str) -> Result<AccessorData> {
        let acc = self.root.accessors.get(a).ok_or_else(|| {
            self.err(format!(
                "{what} names accessor {a}, but the file has {}",
                self.root.accessors.len()
            ))
        })?;
        let fail = |msg: String| self.err(format!("accessor {a} ({what}) {msg}"));
        let Checked::Valid(ct) = acc.component_type else {
            return Err(fail("has an invalid componentType".into()));
        };
        let ct = ct.0;
        let Checked::Valid(ty) = acc.type_ else {
            return Err(fail("has an invalid type".into()));
        };
        let (offsets, elem) = element_layout(ty, ct);
        let ncomp = offsets.len();
        let normalized = acc.normalized && !matches!(ct, ComponentType::F32 | ComponentType::U32);
        let count = usize::try_from(acc.count.0).map_err(|_| fail("has a huge count".into()))?;
        let mut values;
        match acc.buffer_view {
            None => {
                // All zeros (spec 3.6.2.3), usually as the base of a sparse accessor.
                let bytes = count.saturating_mul(elem);
                if bytes > self.input_len {
                    return Err(fail(format!(
                        "has no buffer view but a count of {count}, more than the input could describe"
                    )));
                }
                values = vec![0.0; count * ncomp];
            }
            Some(v) => {
                let (data, stride) =
                    self.view_bytes(v.value(), &format!("accessor {a} ({what})"))?;
                let stride = stride.unwrap_or(elem);
                if stride < elem {
                    return Err(fail(format!(
                        "has {elem}-byte elements but buffer view {v} has byteStride {stride}"
                    )));
                }
                let off = acc.byte_offset.map_or(0, |o| o.0);
                if count > 0 {
                    let need = (count as u64 - 1)
                        .checked_mul(stride as u64)
                        .and_then(|x| x.checked_add(off))
                        .and_then(|x| x.checked_add(elem as u64));
                    if need.is_none_or(|n| n > data.len() as u64) {
                        return Err(fail(format!(
                            "reads past buffer view {v}: {count} elements of {elem} bytes, stride {stride}, from byte {off}, but the view has {} bytes",
                            data.len()
                        )));
                    }
                }
                let off = off as usize;
                values = Vec::with_capacity(count * ncomp);
                for i in 0..count {
                    let start = off + i * stride;
                    values.extend(
                        offsets
                            .iter()
                            .map(|&o| component(data, start + o, ct, normalized)),
                    );
                }
            }
        }
        if let Some(sparse) = &acc.sparse {
            self.apply_sparse(a, what, sparse, count, ct, ty, normalized, &mut values)?;
        }
        Ok(AccessorData {
            values,
            count,
            ncomp,
            component: ct,
        })
    }

    /// Overwrite the elements listed by a sparse accessor's indices with its values (spec
    /// 3.6.2.3), after checking both arrays against their views and the indices against `count`.
    #[allow(clippy::too_many_arguments)]
    fn apply_sparse(
        &self,
        a: usize,
        what: &str,
        sparse: &json::accessor::sparse::Sparse,
        count: usize,
        ct: ComponentType,
        ty: Type,
        normalized: bool,
        values: &mut [f64],
    ) -> Result<()> {
        let fail = |msg: String| self.err(format!("accessor {a} ({what}) {msg}"));
        let n = usize::try_from(sparse.count.0).unwrap_or(usize::MAX);
        if n > count {
            return Err(fail(format!(
                "has {n} sparse entries, more than its {count} elements"
            )));
        }
        let Checked::Valid(ict) = sparse.indices.component_type else {
            return Err(fail("has an invalid sparse index componentType".into()));
        };
        let ict = ict.0;
        if !matches!(
            ict,
            ComponentType::U8 | ComponentType::U16 | ComponentType::U32
        ) {
            return Err(fail(
                "has sparse indices that are not unsigned integers".into(),
            ));
        }
        let ctx = format!("sparse part of accessor {a} ({what})");
        let (ibytes, _) = self.view_bytes(sparse.indices.buffer_view.value(), &ctx)?;
        let (vbytes, _) = self.view_bytes(sparse.values.buffer_view.value(), &ctx)?;
        let ioff = sparse.indices.byte_offset.0;
        let voff = sparse.values.byte_offset.0;
        let (offsets, elem) = element_layout(ty, ct);
        let fits = |off: u64, size: usize, len: usize| {
            (n as u64)
                .checked_mul(size as u64)
                .and_then(|x| x.checked_add(off))
                .is_some_and(|end| end <= len as u64)
        };
        if !fits(ioff, ict.size(), ibytes.len()) || !fits(voff, elem, vbytes.len()) {
            return Err(fail(format!(
                "has {n} sparse entries that read past their buffer views"
            )));
        }
        let ncomp = offsets.len();
        for k in 0..n {
            let idx = component(ibytes, ioff as usize + k * ict.size(), ict, false);
            if idx >= count as f64 {
                return Err(fail(format!(
                    "sparse entry {k} targets element {idx}, but the accessor has {count}"
                )));
            }
            let idx = idx as usize;
            let start = voff as usize + k * elem;
            for (c, &o) in offsets.iter().enumerate() {
                values[idx * ncomp + c] = component(vbytes, start + o, ct, normalized);
            }
        }
        Ok(())
    }

    /// [`Self::accessor`] that also insists on the element type and, when given, the count.
    fn typed(
        &self,
        a: usize,
        what: &str,
        types: &[Type],
        count: Option<usize>,
    ) -> Result<AccessorData> {
        let d = self.accessor(a, what)?;
        let ty = self.root.accessors[a].type_;
        if let Checked::Valid(ty) = ty {
            if !types.contains(&ty) {
                let want: Vec<_> = types.iter().map(|&t| type_name(t)).collect();
                return Err(self.err(format!(
                    "accessor {a} ({what}) has type {}, expected {}",
                    type_name(ty),
                    want.join(" or ")
                )));
            }
        }
        if let Some(n) = count {
            if d.count != n {
                return Err(self.err(format!(
                    "accessor {a} ({what}) has {} elements, but the primitive has {n} vertices",
                    d.count
                )));
            }
        }
        Ok(d)
    }

    /// Parent of every node from the `children` lists; spec 3.5.2 requires a forest, so a node
    /// listed twice is an error. Cycles are caught by [`Self::world_matrices`].
    fn parents(&self) -> Result<Vec<Option<usize>>> {
        let nodes = &self.root.nodes;
        let mut parent = vec![None; nodes.len()];
        for (p, node) in nodes.iter().enumerate() {
            for c in node.children.iter().flatten() {
                let c = c.value();
                let slot = parent.get_mut(c).ok_or_else(|| {
                    self.err(format!(
                        "{} lists child node {c}, but the file has {} nodes",
                        labelled("node", p, node.name.as_deref()),
                        nodes.len()
                    ))
                })?;
                if let Some(q) = *slot {
                    return Err(self.err(format!(
                        "node {c} is a child of both node {q} and node {p}; glTF nodes form a tree (one parent each)"
                    )));
                }
                *slot = Some(p);
            }
        }
        Ok(parent)
    }

    /// Local transform of node `n` (spec 3.5.3: `matrix`, or `T * R * S`), translation in mm.
    fn local_matrix(&self, n: usize) -> Result<Matrix4<f64>> {
        let node = &self.root.nodes[n];
        let m = if let Some(m) = node.matrix {
            let mut m = Matrix4::from_iterator(m.iter().map(|&x| f64::from(x)));
            for r in 0..3 {
                m[(r, 3)] *= self.mm;
            }
            m
        } else {
            let t = node.translation.unwrap_or([0.0; 3]).map(f64::from);
            let q = node
                .rotation
                .as_ref()
                .map_or([0.0, 0.0, 0.0, 1.0], |q| q.0)
                .map(f64::from);
            let s = node.scale.unwrap_or([1.0; 3]).map(f64::from);
            let q = Quaternion::new(q[3], q[0], q[1], q[2]);
            if !q.norm().is_finite() || q.norm() <= 1e-6 {
                return Err(self.err(format!(
                    "{} has a zero or non-finite rotation quaternion",
                    labelled("node", n, node.name.as_deref())
                )));
            }
            let r = UnitQuaternion::from_quaternion(q).to_homogeneous();
            let mut m = r * Matrix4::new_nonuniform_scaling(&Vector3::from(s));
            for k in 0..3 {
                m[(k, 3)] = t[k] * self.mm;
            }
            m
        };
        if !m.iter().all(|x| x.is_finite()) {
            return Err(self.err(format!(
                "{} has a non-finite transform",
                labelled("node", n, node.name.as_deref())
            )));
        }
        Ok(m)
    }

    /// World transform of every node reachable from a root (`parent world * local`, spec
    /// 3.5.3), by one depth-first pass from the parentless nodes; since each node has at most
    /// one parent the pass visits each node once, and nodes on a cycle are never reached (None).
    fn world_matrices(&self, parents: &[Option<usize>]) -> Result<Vec<Option<Matrix4<f64>>>> {
        let nodes = &self.root.nodes;
        let mut world = vec![None; nodes.len()];
        let mut stack: Vec<(usize, Matrix4<f64>)> = (0..nodes.len())
            .rev()
            .filter(|&n| parents[n].is_none())
            .map(|n| (n, Matrix4::identity()))
            .collect();
        while let Some((n, parent_world)) = stack.pop() {
            let w = parent_world * self.local_matrix(n)?;
            world[n] = Some(w);
            for c in nodes[n].children.iter().flatten().rev() {
                stack.push((c.value(), w));
            }
        }
        Ok(world)
    }

    /// Walk the default scene and build one [`SceneMesh`] per mesh node.
    fn scene(&self) -> Result<Scene> {
        let root = self.root;
        let parents = self.parents()?;
        let world = self.world_matrices(&parents)?;
        let roots: Vec<usize> = match root.scene.map(|s| s.value()).or(if root.scenes.is_empty() {
            None
        } else {
            Some(0)
        }) {
            Some(s) => {
                let scene = root.scenes.get(s).ok_or_else(|| {
                    self.err(format!(
                        "'scene' is {s}, but the file has {} scenes",
                        root.scenes.len()
                    ))
                })?;
                let mut r = Vec::with_capacity(scene.nodes.len());
                for n in &scene.nodes {
                    if n.value() >= root.nodes.len() {
                        return Err(self.err(format!(
                            "scene {s} lists node {n}, but the file has {} nodes",
                            root.nodes.len()
                        )));
                    }
                    r.push(n.value());
                }
                r
            }
            None => (0..root.nodes.len())
                .filter(|&n| parents[n].is_none())
                .collect(),
        };

        let mut visited = vec![false; root.nodes.len()];
        let mut skins: HashMap<usize, Vec<SkinJoint>> = HashMap::new();
        let mut meshes = Vec::new();
        let mut skipped: Vec<String> = Vec::new();
        // Instancing (many nodes showing one mesh) multiplies the output; cap it by the input.
        let mut budget = 4 * self.input_len + INSTANCE_SLACK;
        let mut targets: HashMap<usize, AnimationTarget> = HashMap::new();
        let mut stack: Vec<usize> = roots.into_iter().rev().collect();
        while let Some(n) = stack.pop() {
            if std::mem::replace(&mut visited[n], true) {
                continue;
            }
            let node = &root.nodes[n];
            for c in node.children.iter().flatten().rev() {
                stack.push(c.value());
            }
            let Some(m) = node.mesh.map(|m| m.value()) else {
                continue;
            };
            let node_world = world[n].ok_or_else(|| {
                self.err(format!(
                    "{} is on a cycle of the node hierarchy (a node is its own ancestor)",
                    labelled("node", n, node.name.as_deref())
                ))
            })?;
            let skin = match node.skin.map(|s| s.value()) {
                None => None,
                Some(s) => {
                    if let Entry::Vacant(e) = skins.entry(s) {
                        e.insert(self.skin_joints(s, &parents, &world)?);
                    }
                    Some((s, &skins[&s]))
                }
            };
            if let Some(sm) = self.scene_mesh(n, m, &node_world, skin, &mut skipped)? {
                let k = meshes.len();
                targets.entry(n).or_insert(AnimationTarget::Mesh(k));
                if let Some((s, _)) = skin {
                    for (j, jn) in root.skins[s].joints.iter().enumerate() {
                        targets
                            .entry(jn.value())
                            .or_insert(AnimationTarget::Joint { mesh: k, joint: j });
                    }
                }
                let cost = sm.mesh.n_vertices()
                    + sm.mesh.n_faces()
                    + sm.skin.as_ref().map_or(0, |s| s.joints.len());
                budget = budget.checked_sub(cost).ok_or_else(|| {
                    self.err(format!(
                        "{} instantiates meshes so often that the scene would hold more than {} vertices, faces and joints, far more than the file's {} bytes describe",
                        labelled("node", n, node.name.as_deref()),
                        4 * self.input_len + INSTANCE_SLACK,
                        self.input_len
                    ))
                })?;
                meshes.push(sm);
            }
        }
        if meshes.is_empty() {
            let why = if skipped.is_empty() {
                "the default scene has no node with a mesh".to_string()
            } else if skipped.len() <= 3 {
                format!("skipped {}", skipped.join(", "))
            } else {
                format!(
                    "skipped {} and {} more",
                    skipped[..3].join(", "),
                    skipped.len() - 3
                )
            };
            return Err(self.err(format!("no triangle mesh to read: {why}")));
        }
        let animations = self.animations(&targets)?;
        Ok(Scene { meshes, animations })
    }

    /// The animations (spec 3.11) as far as they move what was read: LINEAR `translation` and
    /// `rotation` channels whose node is a mesh node or skin joint of the scene (`targets`).
    /// Other channels (scale, morph weights, STEP or CUBICSPLINE samplers, nodes outside the
    /// scene) are skipped, and an animation left without channels is dropped. Times must be
    /// as many as values; translations come back in mm.
    fn animations(&self, targets: &HashMap<usize, AnimationTarget>) -> Result<Vec<Animation>> {
        use json::animation::{Interpolation, Property};
        let mut out = Vec::new();
        for (a, anim) in self.root.animations.iter().enumerate() {
            let al = labelled("animation", a, anim.name.as_deref());
            let mut channels = Vec::new();
            for (c, ch) in anim.channels.iter().enumerate() {
                let Some(&target) = targets.get(&ch.target.node.value()) else {
                    continue;
                };
                let sampler = anim.samplers.get(ch.sampler.value()).ok_or_else(|| {
                    self.err(format!(
                        "{al} channel {c} names sampler {}, but it has {}",
                        ch.sampler.value(),
                        anim.samplers.len()
                    ))
                })?;
                if sampler.interpolation != Checked::Valid(Interpolation::Linear) {
                    continue;
                }
                let what = format!("{al} channel {c}");
                let (ty, path) = match ch.target.path {
                    Checked::Valid(Property::Translation) => (Type::Vec3, "translation"),
                    Checked::Valid(Property::Rotation) => (Type::Vec4, "rotation"),
                    _ => continue,
                };
                let times = self.typed(
                    sampler.input.value(),
                    &format!("input of {what}"),
                    &[Type::Scalar],
                    None,
                )?;
                let values = self.typed(
                    sampler.output.value(),
                    &format!("output of {what}"),
                    &[ty],
                    None,
                )?;
                if values.count != times.count {
                    return Err(self.err(format!(
                        "{what}: {} {path} values for {} times",
                        values.count, times.count
                    )));
                }
                let values = match ty {
                    Type::Vec3 => Keyframes::Translation(
                        values
                            .values
                            .chunks_exact(3)
                            .map(|v| Vec3::new(v[0], v[1], v[2]) * self.mm)
                            .collect(),
                    ),
                    _ => Keyframes::Rotation(
                        values
                            .values
                            .chunks_exact(4)
                            .map(|v| Quaternion::new(v[3], v[0], v[1], v[2]))
                            .map(|q| {
                                if q.norm().is_finite() && q.norm() > 1e-6 {
                                    Ok(UnitQuaternion::from_quaternion(q))
                                } else {
                                    Err(self.err(format!(
                                        "{what}: a zero or non-finite rotation quaternion"
                                    )))
                                }
                            })
                            .collect::<Result<_>>()?,
                    ),
                };
                channels.push(Channel {
                    target,
                    times: times.values,
                    values,
                });
            }
            if !channels.is_empty() {
                out.push(Animation {
                    name: anim
                        .name
                        .clone()
                        .unwrap_or_else(|| format!("animation {a}")),
                    channels,
                });
            }
        }
        Ok(out)
    }

    /// The joints of skin `s` (spec 3.7.3): names, parents within the skin, local and world
    /// rest transforms and inverse bind matrices, all with translations in mm.
    fn skin_joints(
        &self,
        s: usize,
        parents: &[Option<usize>],
        world: &[Option<Matrix4<f64>>],
    ) -> Result<Vec<SkinJoint>> {
        let root = self.root;
        let skin = root.skins.get(s).ok_or_else(|| {
            self.err(format!(
                "a node names skin {s}, but the file has {}",
                root.skins.len()
            ))
        })?;
        let sl = labelled("skin", s, skin.name.as_deref());
        let mut slot: HashMap<usize, usize> = HashMap::new();
        for (j, node) in skin.joints.iter().enumerate() {
            let node = node.value();
            if node >= root.nodes.len() {
                return Err(self.err(format!(
                    "{sl} joint {j} is node {node}, but the file has {} nodes",
                    root.nodes.len()
                )));
            }
            slot.entry(node).or_insert(j);
        }
        let ibm = match skin.inverse_bind_matrices {
            None => None,
            Some(a) => {
                let what = format!("inverseBindMatrices of {sl}");
                let d = self.typed(a.value(), &what, &[Type::Mat4], None)?;
                if d.count < skin.joints.len() {
                    return Err(self.err(format!(
                        "accessor {a} ({what}) has {} matrices for {} joints",
                        d.count,
                        skin.joints.len()
                    )));
                }
                Some(d.values)
            }
        };
        let mut joints = Vec::with_capacity(skin.joints.len());
        for (j, node) in skin.joints.iter().enumerate() {
            let node = node.value();
            let nd = &root.nodes[node];
            let world = world[node].ok_or_else(|| {
                self.err(format!(
                    "{sl} joint {j} ({}) is on a cycle of the node hierarchy",
                    labelled("node", node, nd.name.as_deref())
                ))
            })?;
            let inverse_bind = match &ibm {
                None => Matrix4::identity(),
                Some(v) => {
                    let mut m = Matrix4::from_column_slice(&v[16 * j..16 * j + 16]);
                    for r in 0..3 {
                        m[(r, 3)] *= self.mm;
                    }
                    if !m.iter().all(|x| x.is_finite()) {
                        return Err(self.err(format!(
                            "inverse bind matrix of {sl} joint {j} is not finite"
                        )));
                    }
                    m
                }
            };
            joints.push(SkinJoint {
                name: nd.name.clone().unwrap_or_else(|| format!("node {node}")),
                parent: parents[node].and_then(|p| slot.get(&p).copied()),
                local: self.local_matrix(node)?,
                world,
                inverse_bind,
            });
        }
        Ok(joints)
    }

    /// The [`SceneMesh`] of node `n` showing mesh `m` (see the module documentation for the
    /// rules); `None` when the mesh has no triangle primitive (the reason goes to `skipped`).
    fn scene_mesh(
        &self,
        n: usize,
        m: usize,
        node_world: &Matrix4<f64>,
        skin: Option<(usize, &Vec<SkinJoint>)>,
        skipped: &mut Vec<String>,
    ) -> Result<Option<SceneMesh>> {
        let root = self.root;
        let node = &root.nodes[n];
        let mesh = root.meshes.get(m).ok_or_else(|| {
            self.err(format!(
                "{} names mesh {m}, but the file has {} meshes",
                labelled("node", n, node.name.as_deref()),
                root.meshes.len()
            ))
        })?;
        let ml = labelled("mesh", m, mesh.name.as_deref());
        let mut vertices: Vec<Point> = Vec::new();
        let mut faces: Vec<[usize; 3]> = Vec::new();
        let mut normals: Vec<Vec3> = Vec::new();
        let mut all_normals = true;
        let mut colors: Vec<[f32; 4]> = Vec::new();
        let mut any_colors = false;
        let mut weights: Vec<Vec<(usize, f64)>> = Vec::new();
        let mut n_tri_prims = 0;
        // Custom attributes every triangle primitive so far has (None before the first).
        let mut custom: Option<Vec<(String, Vec<f32>)>> = None;
        // Morph target displacements, file units (None before the first triangle primitive).
        let mut targets: Option<Vec<Vec<Vec3>>> = None;

        for (pi, prim) in mesh.primitives.iter().enumerate() {
            let pl = format!("primitive {pi} of {ml}");
            let Checked::Valid(mode) = prim.mode else {
                return Err(self.err(format!("{pl} has an invalid mode")));
            };
            if matches!(
                mode,
                Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
            ) {
                skipped.push(format!("{pl} (mode {mode:?}, not triangles)"));
                continue;
            }
            n_tri_prims += 1;
            let attr = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|a| a.value());
            let pos_a = attr(Semantic::Positions)
                .ok_or_else(|| self.err(format!("{pl} has no POSITION attribute")))?;
            let pos = self.typed(pos_a, &format!("POSITION of {pl}"), &[Type::Vec3], None)?;
            let nv = pos.count;
            let offset = vertices.len();

            // Corner indices, then triangles per spec 3.7.2.1 (topology types).
            let idx: Vec<usize> = match prim.indices {
                Some(a) => {
                    let what = format!("indices of {pl}");
                    let d = self.typed(a.value(), &what, &[Type::Scalar], None)?;
                    if !matches!(
                        d.component,
                        ComponentType::U8 | ComponentType::U16 | ComponentType::U32
                    ) {
                        return Err(self.err(format!(
                            "accessor {a} ({what}) has componentType {:?}; indices must be unsigned integers",
                            d.component
                        )));
                    }
                    let mut v = Vec::with_capacity(d.values.len());
                    for (k, &x) in d.values.iter().enumerate() {
                        if x >= nv as f64 {
                            return Err(self.err(format!(
                                "accessor {a} ({what}): index {k} is {x}, but the primitive has {nv} vertices"
                            )));
                        }
                        v.push(x as usize);
                    }
                    v
                }
                None => (0..nv).collect(),
            };
            let tris: Vec<[usize; 3]> = match mode {
                Mode::Triangles => {
                    if !idx.len().is_multiple_of(3) {
                        return Err(self.err(format!(
                            "{pl} has {} corner indices, not a multiple of 3",
                            idx.len()
                        )));
                    }
                    idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
                }
                Mode::TriangleStrip => (0..idx.len().saturating_sub(2))
                    .map(|i| [idx[i], idx[i + 1 + i % 2], idx[i + 2 - i % 2]])
                    .collect(),
                _ => (1..idx.len().saturating_sub(1))
                    .map(|i| [idx[i], idx[i + 1], idx[0]])
                    .collect(),
            };
            faces.extend(
                tris.into_iter()
                    .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
                    .map(|t| t.map(|v| v + offset)),
            );
            vertices.extend(
                pos.values
                    .chunks_exact(3)
                    .map(|c| Point::new(c[0], c[1], c[2])),
            );

            match attr(Semantic::Normals) {
                Some(a) if all_normals => {
                    let d = self.typed(a, &format!("NORMAL of {pl}"), &[Type::Vec3], Some(nv))?;
                    normals.extend(
                        d.values
                            .chunks_exact(3)
                            .map(|c| Vec3::new(c[0], c[1], c[2])),
                    );
                }
                Some(_) => {}
                None => all_normals = false,
            }

            match attr(Semantic::Colors(0)) {
                Some(a) => {
                    let what = format!("COLOR_0 of {pl}");
                    let d = self.typed(a, &what, &[Type::Vec3, Type::Vec4], Some(nv))?;
                    if !any_colors {
                        colors.resize(offset, [1.0; 4]);
                        any_colors = true;
                    }
                    for c in d.values.chunks_exact(d.ncomp) {
                        if !c.iter().all(|x| x.is_finite()) {
                            return Err(
                                self.err(format!("accessor {a} ({what}) has a non-finite colour"))
                            );
                        }
                        let alpha = if d.ncomp == 4 { c[3] as f32 } else { 1.0 };
                        colors.push([c[0] as f32, c[1] as f32, c[2] as f32, alpha]);
                    }
                }
                None if any_colors => colors.resize(offset + nv, [1.0; 4]),
                None => {}
            }

            let mut mine = Vec::new();
            for (sem, a) in &prim.attributes {
                let Checked::Valid(Semantic::Extras(name)) = sem else {
                    continue;
                };
                let a = a.value();
                let float_scalar = self.root.accessors.get(a).is_some_and(|acc| {
                    matches!(acc.type_, Checked::Valid(Type::Scalar))
                        && matches!(acc.component_type, Checked::Valid(c) if c.0 == ComponentType::F32)
                });
                if !float_scalar {
                    continue;
                }
                let what = format!("_{name} of {pl}");
                let d = self.typed(a, &what, &[Type::Scalar], Some(nv))?;
                mine.push((
                    format!("_{name}"),
                    d.values.iter().map(|&x| x as f32).collect::<Vec<_>>(),
                ));
            }
            custom = Some(match custom.take() {
                None => mine,
                Some(before) => before
                    .into_iter()
                    .filter_map(|(name, mut values)| {
                        let (_, more) = mine.iter().find(|(n, _)| *n == name)?;
                        values.extend_from_slice(more);
                        Some((name, values))
                    })
                    .collect(),
            });

            let prim_targets = prim.targets.as_deref().unwrap_or(&[]);
            let all = targets.get_or_insert_with(|| vec![Vec::new(); prim_targets.len()]);
            if all.len() != prim_targets.len() {
                return Err(self.err(format!(
                    "{pl} has {} morph targets, but an earlier primitive of {ml} has {}; glTF requires the same number on every primitive of a mesh",
                    prim_targets.len(),
                    all.len()
                )));
            }
            for (k, (t, out)) in prim_targets.iter().zip(all.iter_mut()).enumerate() {
                match &t.positions {
                    Some(a) => {
                        let what = format!("POSITION of morph target {k} of {pl}");
                        let d = self.typed(a.value(), &what, &[Type::Vec3], Some(nv))?;
                        if !d.values.iter().all(|x| x.is_finite()) {
                            return Err(self.err(format!(
                                "accessor {a} ({what}) has a non-finite displacement"
                            )));
                        }
                        out.extend(
                            d.values
                                .chunks_exact(3)
                                .map(|c| Vec3::new(c[0], c[1], c[2])),
                        );
                    }
                    None => out.resize(offset + nv, Vec3::zeros()),
                }
            }

            if let Some((s, joints)) = skin {
                let mut w = vec![Vec::new(); nv];
                let mut set = 0u32;
                while let (Some(ja), Some(wa)) =
                    (attr(Semantic::Joints(set)), attr(Semantic::Weights(set)))
                {
                    self.add_weights(&mut w, ja, wa, set, &pl, s, joints.len())?;
                    set += 1;
                }
                weights.extend(w.into_iter().map(finish_weights));
            }
        }
        if n_tri_prims == 0 {
            return Ok(None);
        }

        let skinned = skin.is_some();
        for p in &mut vertices {
            p.coords *= self.mm;
            if !skinned {
                *p = node_world.transform_point(p);
            }
        }
        let mut normals = (all_normals && n_tri_prims > 0).then_some(normals);
        if let Some(ns) = &mut normals {
            let nm: Matrix3<f64> = if skinned {
                Matrix3::identity()
            } else {
                let l = node_world.fixed_view::<3, 3>(0, 0).into_owned();
                l.try_inverse().map_or(l, |i| i.transpose())
            };
            for (k, v) in ns.iter_mut().enumerate() {
                if !v.iter().all(|x| x.is_finite()) {
                    return Err(self.err(format!("{ml}: normal of vertex {k} is not finite")));
                }
                *v = (nm * *v).try_normalize(0.0).unwrap_or_else(Vec3::zeros);
            }
        }
        if !skinned && node_world.fixed_view::<3, 3>(0, 0).determinant() < 0.0 {
            for f in &mut faces {
                f.swap(1, 2);
            }
        }
        let linear: Matrix3<f64> = if skinned {
            Matrix3::identity()
        } else {
            node_world.fixed_view::<3, 3>(0, 0).into_owned()
        };
        let targets = targets.unwrap_or_default();
        let names: Vec<String> = mesh
            .extras
            .as_ref()
            .and_then(|raw| serde_json::from_str::<serde_json::Value>(raw.get()).ok())
            .and_then(|v| {
                v.get("targetNames")?
                    .as_array()?
                    .iter()
                    .map(|n| n.as_str().map(str::to_string))
                    .collect::<Option<Vec<_>>>()
            })
            .filter(|n| n.len() == targets.len())
            .unwrap_or_else(|| (0..targets.len()).map(|k| format!("target {k}")).collect());
        let default_weights = mesh.weights.as_deref().unwrap_or(&[]);
        let morph_targets = targets
            .into_iter()
            .zip(names)
            .enumerate()
            .map(|(k, (d, name))| MorphTarget {
                name,
                displacements: d.into_iter().map(|x| linear * x * self.mm).collect(),
                weight: default_weights.get(k).map_or(0.0, |&w| f64::from(w)),
            })
            .collect();
        let attributes = custom
            .unwrap_or_default()
            .into_iter()
            .map(|(name, values)| VertexAttribute { name, values })
            .collect();
        let name = node
            .name
            .clone()
            .or_else(|| mesh.name.clone())
            .unwrap_or_else(|| format!("mesh {m}"));
        let tri = TriMesh::new(vertices, faces).map_err(|e| match e {
            Error::Invalid(msg) => self.err(format!("{ml}: {msg}")),
            other => other,
        })?;
        let skin = skin.map(|(_, joints)| Skin {
            joints: joints.clone(),
            weights,
        });
        Ok(Some(SceneMesh {
            name,
            mesh: tri,
            normals,
            colors: any_colors.then_some(colors),
            skin,
            attributes,
            morph_targets,
        }))
    }

    /// Accumulate one `JOINTS_n`/`WEIGHTS_n` pair (spec 3.7.3 "Skins") into per-vertex lists; zero
    /// weights are ignored (their joint index may be anything), a weighted joint index must
    /// name a joint of the skin, and a weight must be finite and non-negative.
    #[allow(clippy::too_many_arguments)]
    fn add_weights(
        &self,
        w: &mut [Vec<(usize, f64)>],
        ja: usize,
        wa: usize,
        set: u32,
        pl: &str,
        s: usize,
        n_joints: usize,
    ) -> Result<()> {
        let nv = w.len();
        let jwhat = format!("JOINTS_{set} of {pl}");
        let wwhat = format!("WEIGHTS_{set} of {pl}");
        let jd = self.typed(ja, &jwhat, &[Type::Vec4], Some(nv))?;
        if matches!(jd.component, ComponentType::F32) || self.root.accessors[ja].normalized {
            return Err(self.err(format!(
                "accessor {ja} ({jwhat}) must hold unsigned integers (u8 or u16), not normalised or float values"
            )));
        }
        let wd = self.typed(wa, &wwhat, &[Type::Vec4], Some(nv))?;
        for (v, slots) in w.iter_mut().enumerate() {
            for k in 0..4 {
                let weight = wd.values[4 * v + k];
                if !(weight >= 0.0 && weight.is_finite()) {
                    return Err(self.err(format!(
                        "accessor {wa} ({wwhat}): vertex {v} has weight {weight}; weights must be finite and non-negative"
                    )));
                }
                if weight == 0.0 {
                    continue;
                }
                let joint = jd.values[4 * v + k];
                if joint < 0.0 || joint >= n_joints as f64 {
                    return Err(self.err(format!(
                        "accessor {ja} ({jwhat}): vertex {v} names joint {joint}, but skin {s} has {n_joints} joints"
                    )));
                }
                let joint = joint as usize;
                match slots.iter_mut().find(|(j, _)| *j == joint) {
                    Some(slot) => slot.1 += weight,
                    None => slots.push((joint, weight)),
                }
            }
        }
        Ok(())
    }
}

/// Keep a vertex's 4 largest weights (ties by joint index, for determinism), normalised to
/// sum 1; no weight stays empty.
fn finish_weights(mut w: Vec<(usize, f64)>) -> Vec<(usize, f64)> {
    w.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    w.truncate(4);
    let sum: f64 = w.iter().map(|x| x.1).sum();
    if sum > 0.0 {
        for x in &mut w {
            x.1 /= sum;
        }
    }
    w
}
