//! The GLB writer (see [`super::glb_bytes`] for the layout and the checks).

use super::animation::{write_animations, NodeMap};
use super::buffer::{f32s, Bin, FLOAT};
use super::container::compose_glb;
use super::{Scene, SceneMesh, Skin, SkinJoint};
use crate::error::{Error, Result};
use crate::geometry::Vec3;
use crate::io::Units;
use nalgebra::{Matrix3, Matrix4, Rotation3, UnitQuaternion, Vector3};
use serde_json::{json, Map, Value};

/// glTF enums (spec 5.1.1 accessor.componentType, 5.11.4 bufferView.target, 5.24.4 mode).
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const TRIANGLES: u32 = 4;

/// Relative tolerance for "this matrix is that matrix" (joint chains, TRS decomposition):
/// well above f64 round-off of products of f32 data, well below anything a user would mean.
const MATRIX_TOL: f64 = 1e-6;

/// Largest absolute entry, the scale for [`MATRIX_TOL`].
fn max_abs(m: &Matrix4<f64>) -> f64 {
    m.iter().fold(0.0f64, |a, x| a.max(x.abs()))
}

fn close(a: &Matrix4<f64>, b: &Matrix4<f64>) -> bool {
    max_abs(&(a - b)) <= MATRIX_TOL * (1.0 + max_abs(a).max(max_abs(b)))
}

/// `m` with its translation column divided by `mm_per_unit` (the inverse of the reader's
/// conjugation by `diag(s, s, s, 1)`).
fn to_units(m: &Matrix4<f64>, mm_per_unit: f64) -> Matrix4<f64> {
    let mut m = *m;
    for r in 0..3 {
        m[(r, 3)] /= mm_per_unit;
    }
    m
}

/// Split an affine matrix into glTF node properties `translation`, `rotation` (x, y, z, w) and
/// `scale` with `M = T * R * S` (spec 3.5.3), or `None` when it has shear or projection, which
/// glTF cannot store (spec: a node matrix "MUST be decomposable to TRS properties").
/// Scale is the column norms, negated on x when the matrix mirrors, so R is a proper rotation.
fn decompose_trs(m: &Matrix4<f64>) -> Option<(Vector3<f64>, UnitQuaternion<f64>, Vector3<f64>)> {
    let tol = MATRIX_TOL * (1.0 + max_abs(m));
    if (m.fixed_view::<1, 4>(3, 0) - nalgebra::RowVector4::new(0.0, 0.0, 0.0, 1.0)).amax() > tol {
        return None;
    }
    let l: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let mut s = Vector3::from_fn(|k, _| l.column(k).norm());
    if s.iter().any(|&x| x <= f64::MIN_POSITIVE) {
        return None;
    }
    if l.determinant() < 0.0 {
        s.x = -s.x;
    }
    let r = Matrix3::from_fn(|i, k| l[(i, k)] / s[k]);
    if (r.transpose() * r - Matrix3::identity()).amax() > 1e-5 {
        return None;
    }
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let t = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
    let back =
        Matrix4::new_translation(&t) * q.to_homogeneous() * Matrix4::new_nonuniform_scaling(&s);
    close(&back, m).then_some((t, q, s))
}

/// A glTF node object with `name` and the TRS of `m` (defaults omitted).
fn trs_node(name: &str, m: &Matrix4<f64>, what: &dyn Fn() -> String) -> Result<Map<String, Value>> {
    let (t, q, s) = decompose_trs(m).ok_or_else(|| {
        Error::invalid(format!(
            "{}: the transform has shear or projection, which glTF nodes cannot store",
            what()
        ))
    })?;
    let mut node = Map::new();
    node.insert("name".into(), json!(name));
    let f = |x: f64| f64::from(x as f32);
    if t != Vector3::zeros() {
        node.insert("translation".into(), json!([f(t.x), f(t.y), f(t.z)]));
    }
    if q.angle() != 0.0 {
        // Normalised in f32 so the stored quaternion is unit to f32 precision (validator check).
        let c = q.coords.map(|x| x as f32);
        let n = c.norm();
        node.insert(
            "rotation".into(),
            json!([c.x / n, c.y / n, c.z / n, c.w / n].map(f64::from)),
        );
    }
    if s != Vector3::repeat(1.0) {
        node.insert("scale".into(), json!([f(s.x), f(s.y), f(s.z)]));
    }
    Ok(node)
}

/// See [`super::glb_bytes`].
pub(super) fn glb_bytes(scene: &Scene, units: Units) -> Result<Vec<u8>> {
    let mm = units.to_mm();
    let mut bin = Bin::default();
    let mut nodes: Vec<Value> = Vec::new();
    let mut meshes: Vec<Value> = Vec::new();
    let mut skins: Vec<Value> = Vec::new();
    let mut scene_nodes: Vec<usize> = Vec::new();
    if scene.meshes.is_empty() {
        return Err(Error::invalid("the scene has no mesh to write"));
    }
    let mut node_map = NodeMap::default();
    for sm in &scene.meshes {
        let node_index = nodes.len();
        scene_nodes.push(node_index);
        node_map.mesh.push(node_index);
        node_map
            .joints
            .push(sm.skin.as_ref().map(|s| (node_index + 1, s.joints.len())));
        let (attributes, indices) = write_mesh(&mut bin, sm, mm)?;
        let mut node = json!({ "name": sm.name, "mesh": meshes.len() });
        let mut primitive = json!({
            "attributes": attributes,
            "indices": indices,
            "material": 0,
            "mode": TRIANGLES,
        });
        let mut mesh = json!({ "name": sm.name });
        if !sm.morph_targets.is_empty() {
            let targets = write_morph_targets(&mut bin, sm, mm)?;
            primitive["targets"] = Value::Array(targets);
            mesh["weights"] = json!(sm
                .morph_targets
                .iter()
                .map(|t| f64::from(t.weight as f32))
                .collect::<Vec<_>>());
            mesh["extras"] = json!({
                "targetNames": sm.morph_targets.iter().map(|t| t.name.as_str()).collect::<Vec<_>>(),
            });
        }
        mesh["primitives"] = json!([primitive]);
        meshes.push(mesh);
        nodes.push(Value::Null);
        if let Some(skin) = &sm.skin {
            node["skin"] = json!(skins.len());
            skins.push(write_skin(
                &mut bin,
                &mut nodes,
                &mut scene_nodes,
                sm,
                skin,
                mm,
            )?);
        }
        nodes[node_index] = node;
    }
    let mut root = json!({
        "asset": {
            "version": "2.0",
            "generator": concat!("ergohand ", env!("CARGO_PKG_VERSION")),
        },
        "scene": 0,
        "scenes": [{ "name": "ergohand", "nodes": scene_nodes }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": [{
            "name": "skin",
            "pbrMetallicRoughness": {
                "baseColorFactor": [0.8, 0.8, 0.8, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.6,
            },
        }],
    });
    if !skins.is_empty() {
        root["skins"] = Value::Array(skins);
    }
    let animations = write_animations(&mut bin, scene, &node_map, mm)?;
    if !animations.is_empty() {
        root["animations"] = Value::Array(animations);
    }
    // The animation accessors were added after the root was assembled.
    root["buffers"] = json!([{ "byteLength": bin.data.len() }]);
    root["bufferViews"] = Value::Array(std::mem::take(&mut bin.views));
    root["accessors"] = Value::Array(std::mem::take(&mut bin.accessors));
    let text = serde_json::to_vec(&root).map_err(|e| Error::invalid(format!("glTF JSON: {e}")))?;
    compose_glb(&text, &bin.data).map_err(Error::invalid)
}

/// Write the vertex attributes and indices of `sm`; returns the `attributes` object and the
/// index accessor.
fn write_mesh(bin: &mut Bin, sm: &SceneMesh, mm: f64) -> Result<(Value, usize)> {
    let name = &sm.name;
    let mesh = &sm.mesh;
    let nv = mesh.vertices.len();
    let bad = |msg: String| Error::invalid(format!("scene mesh '{name}': {msg}"));
    if nv == 0 || mesh.faces.is_empty() {
        return Err(bad(
            "has no triangles; glTF cannot store an empty mesh".into()
        ));
    }
    if u32::try_from(nv).is_err() {
        return Err(bad(format!(
            "has {nv} vertices, more than u32 indices can address"
        )));
    }
    let check_len = |what: &str, n: usize| {
        if n == nv {
            Ok(())
        } else {
            Err(bad(format!("has {n} {what} for {nv} vertices")))
        }
    };

    let mut pos = Vec::with_capacity(nv * 3);
    for (v, p) in mesh.vertices.iter().enumerate() {
        let q = p.coords.map(|x| (x / mm) as f32);
        if !q.iter().all(|x| x.is_finite()) {
            return Err(bad(format!("vertex {v} is not finite in f32")));
        }
        pos.extend_from_slice(q.as_slice());
    }
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for c in pos.chunks_exact(3) {
        for k in 0..3 {
            lo[k] = lo[k].min(c[k]);
            hi[k] = hi[k].max(c[k]);
        }
    }
    let mut attributes = Map::new();
    let mut extra = Map::new();
    extra.insert("min".into(), json!(lo.map(f64::from)));
    extra.insert("max".into(), json!(hi.map(f64::from)));
    let a = bin.accessor(&f32s(pos), FLOAT, nv, "VEC3", Some(ARRAY_BUFFER), extra);
    attributes.insert("POSITION".into(), json!(a));

    if let Some(normals) = &sm.normals {
        check_len("normals", normals.len())?;
        let mut fallback: Option<Vec<Vec3>> = None;
        let mut out = Vec::with_capacity(nv * 3);
        for (v, n) in normals.iter().enumerate() {
            let unit = match n
                .try_normalize(1e-12)
                .filter(|u| u.iter().all(|x| x.is_finite()))
            {
                Some(u) => u,
                None => fallback.get_or_insert_with(|| mesh.vertex_normals())[v]
                    .try_normalize(0.0)
                    .unwrap_or_else(Vec3::z),
            };
            let f = unit.map(|x| x as f32);
            let f = f / f.norm();
            out.extend_from_slice(f.as_slice());
        }
        let a = bin.accessor(
            &f32s(out),
            FLOAT,
            nv,
            "VEC3",
            Some(ARRAY_BUFFER),
            Map::new(),
        );
        attributes.insert("NORMAL".into(), json!(a));
    }
    if let Some(colors) = &sm.colors {
        check_len("colours", colors.len())?;
        let mut out = Vec::with_capacity(nv * 4);
        for (v, c) in colors.iter().enumerate() {
            if !c.iter().all(|x| x.is_finite()) {
                return Err(bad(format!("colour of vertex {v} is not finite")));
            }
            out.extend(c.iter().map(|x| x.clamp(0.0, 1.0)));
        }
        let a = bin.accessor(
            &f32s(out),
            FLOAT,
            nv,
            "VEC4",
            Some(ARRAY_BUFFER),
            Map::new(),
        );
        attributes.insert("COLOR_0".into(), json!(a));
    }

    for (k, attr) in sm.attributes.iter().enumerate() {
        let an = &attr.name;
        if !an.starts_with('_') || an.len() < 2 {
            return Err(bad(format!(
                "custom attribute {k} is named '{an}'; glTF requires application-specific attribute names to start with '_' (e.g. '_DISTANCE_MM')"
            )));
        }
        if sm.attributes[..k].iter().any(|a| a.name == *an) || attributes.contains_key(an) {
            return Err(bad(format!("custom attribute '{an}' is given twice")));
        }
        check_len(&format!("values of attribute '{an}'"), attr.values.len())?;
        if let Some(v) = attr.values.iter().position(|x| !x.is_finite()) {
            return Err(bad(format!("attribute '{an}' of vertex {v} is not finite")));
        }
        let a = bin.accessor(
            &f32s(attr.values.iter().copied()),
            FLOAT,
            nv,
            "SCALAR",
            Some(ARRAY_BUFFER),
            Map::new(),
        );
        attributes.insert(an.clone(), json!(a));
    }

    let mut idx = Vec::with_capacity(mesh.faces.len() * 12);
    for (f, face) in mesh.faces.iter().enumerate() {
        for &v in face {
            if v >= nv {
                return Err(bad(format!(
                    "face {f} names vertex {v}, but there are {nv}"
                )));
            }
            idx.extend_from_slice(&(v as u32).to_le_bytes());
        }
    }
    let indices = bin.accessor(
        &idx,
        UNSIGNED_INT,
        mesh.faces.len() * 3,
        "SCALAR",
        Some(ELEMENT_ARRAY_BUFFER),
        Map::new(),
    );
    if let Some(skin) = &sm.skin {
        let (j, w) = write_skin_attributes(bin, sm, skin)?;
        attributes.insert("JOINTS_0".into(), json!(j));
        attributes.insert("WEIGHTS_0".into(), json!(w));
    }
    Ok((Value::Object(attributes), indices))
}

/// The primitive's `targets` of `sm` (spec 3.7.2.2 "Morph Targets"): per target a `POSITION`
/// accessor of displacements in the file's unit with the `min`/`max` the spec requires of it.
fn write_morph_targets(bin: &mut Bin, sm: &SceneMesh, mm: f64) -> Result<Vec<Value>> {
    let name = &sm.name;
    let nv = sm.mesh.vertices.len();
    let bad = |msg: String| Error::invalid(format!("scene mesh '{name}': {msg}"));
    let mut out = Vec::with_capacity(sm.morph_targets.len());
    for (k, t) in sm.morph_targets.iter().enumerate() {
        let tl = format!("morph target {k} ('{}')", t.name);
        if t.displacements.len() != nv {
            return Err(bad(format!(
                "{tl} has {} displacements for {nv} vertices",
                t.displacements.len()
            )));
        }
        if !(t.weight as f32).is_finite() {
            return Err(bad(format!("{tl} has weight {}", t.weight)));
        }
        let mut d = Vec::with_capacity(nv * 3);
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for (v, x) in t.displacements.iter().enumerate() {
            let q = x.map(|c| (c / mm) as f32);
            if !q.iter().all(|c| c.is_finite()) {
                return Err(bad(format!(
                    "{tl}: displacement of vertex {v} is not finite in f32"
                )));
            }
            for c in 0..3 {
                lo[c] = lo[c].min(q[c]);
                hi[c] = hi[c].max(q[c]);
            }
            d.extend_from_slice(q.as_slice());
        }
        let mut extra = Map::new();
        extra.insert("min".into(), json!(lo.map(f64::from)));
        extra.insert("max".into(), json!(hi.map(f64::from)));
        let a = bin.accessor(&f32s(d), FLOAT, nv, "VEC3", Some(ARRAY_BUFFER), extra);
        out.push(json!({ "POSITION": a }));
    }
    Ok(out)
}

/// `JOINTS_0` (u16) and `WEIGHTS_0` (f32) of a skinned mesh (spec 3.7.3 "Skins"): per vertex the
/// 4 largest weights (duplicate joints merged), renormalised so the f32 sum is 1 within one
/// ulp (the validator's check), padded with joint 0 and weight 0.
fn write_skin_attributes(bin: &mut Bin, sm: &SceneMesh, skin: &Skin) -> Result<(usize, usize)> {
    let name = &sm.name;
    let nv = sm.mesh.vertices.len();
    let nj = skin.joints.len();
    let bad = |msg: String| Error::invalid(format!("scene mesh '{name}': {msg}"));
    if skin.weights.len() != nv {
        return Err(bad(format!(
            "skin has weights for {} vertices, the mesh has {nv}",
            skin.weights.len()
        )));
    }
    let mut joints = Vec::with_capacity(nv * 8);
    let mut weights = Vec::with_capacity(nv * 4);
    for (v, list) in skin.weights.iter().enumerate() {
        let mut merged: Vec<(usize, f64)> = Vec::with_capacity(list.len());
        for &(j, w) in list {
            if j >= nj {
                return Err(bad(format!(
                    "vertex {v} names joint {j}, but the skin has {nj}"
                )));
            }
            if !(w.is_finite() && w >= 0.0) {
                return Err(bad(format!("vertex {v} has weight {w} for joint {j}")));
            }
            if w == 0.0 {
                continue;
            }
            match merged.iter_mut().find(|(k, _)| *k == j) {
                Some(e) => e.1 += w,
                None => merged.push((j, w)),
            }
        }
        merged.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        merged.truncate(4);
        let sum: f64 = merged.iter().map(|x| x.1).sum();
        if merged.is_empty() || sum <= 0.0 {
            return Err(bad(format!(
                "vertex {v} has no skin weight; glTF needs every vertex of a skinned mesh bound to a joint"
            )));
        }
        let mut w4 = [0f32; 4];
        let mut j4 = [0u16; 4];
        for (k, &(j, w)) in merged.iter().enumerate() {
            j4[k] = j as u16;
            w4[k] = (w / sum) as f32;
        }
        // Put the f32 rounding residue on the largest weight so the stored sum is 1.
        let s32: f32 = w4.iter().sum();
        w4[0] += 1.0 - s32;
        joints.extend(j4.iter().flat_map(|j| j.to_le_bytes()));
        weights.extend(w4);
    }
    let j = bin.accessor(
        &joints,
        UNSIGNED_SHORT,
        nv,
        "VEC4",
        Some(ARRAY_BUFFER),
        Map::new(),
    );
    let w = bin.accessor(
        &f32s(weights),
        FLOAT,
        nv,
        "VEC4",
        Some(ARRAY_BUFFER),
        Map::new(),
    );
    Ok((j, w))
}

/// The joint nodes, inverse bind matrices and `skin` object of `sm` (spec 3.7.3); joint `j`
/// becomes node `nodes.len() + j`, root joints join the scene (under a parent node holding
/// `world * local^-1` when their world and local differ).
fn write_skin(
    bin: &mut Bin,
    nodes: &mut Vec<Value>,
    scene_nodes: &mut Vec<usize>,
    sm: &SceneMesh,
    skin: &Skin,
    mm: f64,
) -> Result<Value> {
    let name = &sm.name;
    let joints = &skin.joints;
    let nj = joints.len();
    let bad = |msg: String| Error::invalid(format!("scene mesh '{name}': {msg}"));
    if nj == 0 || nj > usize::from(u16::MAX) + 1 {
        return Err(bad(format!(
            "skin has {nj} joints; glTF with u16 JOINTS_0 needs 1 to 65536"
        )));
    }
    check_joints(joints).map_err(|m| bad(format!("skin {m}")))?;

    let base = nodes.len();
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); nj];
    for (j, joint) in joints.iter().enumerate() {
        if let Some(p) = joint.parent {
            children[p].push(base + j);
        }
    }
    let mut extra_nodes = Vec::new();
    for (j, joint) in joints.iter().enumerate() {
        let what = || format!("scene mesh '{name}': joint {j} ('{}')", joint.name);
        let mut node = trs_node(&joint.name, &to_units(&joint.local, mm), &what)?;
        if !children[j].is_empty() {
            node.insert("children".into(), json!(children[j]));
        }
        nodes.push(Value::Object(node));
        if joint.parent.is_none() {
            if close(&joint.world, &joint.local) {
                scene_nodes.push(base + j);
            } else {
                let inv = joint.local.try_inverse().ok_or_else(|| {
                    Error::invalid(format!("{}: local transform is singular", what()))
                })?;
                let up = to_units(&(joint.world * inv), mm);
                let mut holder = trs_node(&format!("{} parent", joint.name), &up, &what)?;
                holder.insert("children".into(), json!([base + j]));
                extra_nodes.push(Value::Object(holder));
            }
        }
    }
    for holder in extra_nodes {
        scene_nodes.push(nodes.len());
        nodes.push(holder);
    }

    let mut ibm = Vec::with_capacity(nj * 16);
    for (j, joint) in joints.iter().enumerate() {
        let m = to_units(&joint.inverse_bind, mm).map(|x| x as f32);
        if !m.iter().all(|x| x.is_finite()) {
            return Err(bad(format!(
                "joint {j} ('{}'): inverse bind matrix is not finite",
                joint.name
            )));
        }
        ibm.extend_from_slice(m.as_slice());
    }
    let a = bin.accessor(&f32s(ibm), FLOAT, nj, "MAT4", None, Map::new());
    Ok(json!({
        "name": format!("{name} skin"),
        "joints": (base..base + nj).collect::<Vec<_>>(),
        "inverseBindMatrices": a,
    }))
}

/// Parents in range and acyclic, transforms finite, and every joint with a parent placed at
/// `parent.world * local` (the file stores only locals, so anything else could not round-trip).
fn check_joints(joints: &[SkinJoint]) -> std::result::Result<(), String> {
    let nj = joints.len();
    for (j, joint) in joints.iter().enumerate() {
        let jl = format!("joint {j} ('{}')", joint.name);
        for (what, m) in [
            ("local", &joint.local),
            ("world", &joint.world),
            ("inverse bind", &joint.inverse_bind),
        ] {
            if !m.iter().all(|x| x.is_finite()) {
                return Err(format!("{jl}: {what} transform is not finite"));
            }
        }
        let mut p = joint.parent;
        let mut steps = 0;
        while let Some(q) = p {
            if q >= nj {
                return Err(format!(
                    "{jl}: an ancestor names parent {q}, but there are {nj} joints"
                ));
            }
            steps += 1;
            if steps > nj {
                return Err(format!("{jl}: the parent chain has a cycle"));
            }
            p = joints[q].parent;
        }
        if let Some(q) = joint.parent {
            let expect = joints[q].world * joint.local;
            if !close(&expect, &joint.world) {
                return Err(format!(
                    "{jl}: world transform differs from parent world * local by {:.3e}; update world (or local) so they agree",
                    max_abs(&(expect - joint.world))
                ));
            }
        }
    }
    Ok(())
}
