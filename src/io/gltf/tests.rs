use super::container::{base64_encode, compose_glb};
use super::*;
use crate::geometry::Point;
use nalgebra::{Matrix4, Rotation3, Vector3};
use proptest::prelude::*;
use serde_json::{json, Value};
use std::path::PathBuf;

fn asset(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("assets/generic-hand")
        .join(name)
}

fn label() -> PathBuf {
    PathBuf::from("test.glb")
}

/// The JSON chunk of a GLB, parsed independently of the reader (spec 4.4: 12-byte header,
/// then chunk length, chunk type, JSON).
fn glb_json(bytes: &[u8]) -> Value {
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&bytes[20..20 + len]).unwrap()
}

fn max_diff(a: &Matrix4<f64>, b: &Matrix4<f64>) -> f64 {
    (a - b).amax()
}

/// The 25 WebXR hand joint names (WebXR Hand Input, section 3.2 "XRHand"), which the
/// generic-hand assets use for their joint nodes.
const WEBXR_JOINTS: [&str; 25] = [
    "wrist",
    "thumb-metacarpal",
    "thumb-phalanx-proximal",
    "thumb-phalanx-distal",
    "thumb-tip",
    "index-finger-metacarpal",
    "index-finger-phalanx-proximal",
    "index-finger-phalanx-intermediate",
    "index-finger-phalanx-distal",
    "index-finger-tip",
    "middle-finger-metacarpal",
    "middle-finger-phalanx-proximal",
    "middle-finger-phalanx-intermediate",
    "middle-finger-phalanx-distal",
    "middle-finger-tip",
    "ring-finger-metacarpal",
    "ring-finger-phalanx-proximal",
    "ring-finger-phalanx-intermediate",
    "ring-finger-phalanx-distal",
    "ring-finger-tip",
    "pinky-finger-metacarpal",
    "pinky-finger-phalanx-proximal",
    "pinky-finger-phalanx-intermediate",
    "pinky-finger-phalanx-distal",
    "pinky-finger-tip",
];

fn check_weights(w: &[(usize, f64)], n_joints: usize) {
    assert!(!w.is_empty() && w.len() <= 4, "{w:?}");
    let sum: f64 = w.iter().map(|x| x.1).sum();
    assert!((sum - 1.0).abs() < 1e-12, "{w:?}");
    for pair in w.windows(2) {
        assert!(pair[0].1 >= pair[1].1, "not sorted: {w:?}");
        assert_ne!(pair[0].0, pair[1].0, "duplicate joint: {w:?}");
    }
    assert!(w.iter().all(|&(j, x)| j < n_joints && x > 0.0));
}

#[test]
fn generic_hands_read_as_documented() {
    for file in ["right.glb", "left.glb"] {
        let path = asset(file);
        let bytes = std::fs::read(&path).unwrap();
        let scene = read_gltf(&path, Units::Metres).unwrap();
        assert_eq!(
            scene,
            read_gltf_slice(&bytes, Units::Metres, &path).unwrap()
        );
        assert_eq!(scene.meshes.len(), 1);
        let sm = &scene.meshes[0];
        assert_eq!(sm.mesh.n_vertices(), 1360, "{file}");
        assert_eq!(sm.mesh.n_faces(), 2314, "{file}");
        assert_eq!(sm.normals.as_ref().unwrap().len(), 1360);
        assert!(sm.colors.is_none());
        for n in sm.normals.as_ref().unwrap() {
            assert!((n.norm() - 1.0).abs() < 1e-9);
        }

        // Skinned: positions are the stored ones, so the bounds are the POSITION accessor's
        // min/max (spec-required, written by the exporter) times 1000.
        let json = glb_json(&bytes);
        let pos_acc = json["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
            .as_u64()
            .unwrap();
        let acc = &json["accessors"][pos_acc as usize];
        let (lo, hi) = sm.mesh.bounds().unwrap();
        for k in 0..3 {
            let min = acc["min"][k].as_f64().unwrap() * 1000.0;
            let max = acc["max"][k].as_f64().unwrap() * 1000.0;
            assert!(
                (lo[k] - min).abs() < 1e-4 && (hi[k] - max).abs() < 1e-4,
                "{file} axis {k}"
            );
        }
        // An adult hand: fingers along -Y, about 190 mm from wrist to fingertip plus the stub
        // of forearm; the wrist-to-middle-fingertip joint distance is a hand length.
        assert!(
            (150.0..250.0).contains(&(hi.y - lo.y)),
            "{file}: {}",
            hi.y - lo.y
        );

        let skin = sm.skin.as_ref().unwrap();
        let names: Vec<&str> = skin.joints.iter().map(|j| j.name.as_str()).collect();
        let mut sorted = names.clone();
        sorted.sort_unstable();
        let mut want = WEBXR_JOINTS;
        want.sort_unstable();
        assert_eq!(sorted, want, "{file} (the left hand lists them in reverse)");
        let joint = |n: &str| &skin.joints[names.iter().position(|x| *x == n).unwrap()];
        let t = |m: &Matrix4<f64>| Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
        let length = (t(&joint("wrist").world) - t(&joint("middle-finger-tip").world)).norm();
        assert!((160.0..200.0).contains(&length), "{file}: {length}");

        // Flat siblings under the non-joint "Armature" node (which has no transform).
        for j in &skin.joints {
            assert_eq!(j.parent, None);
            assert!(max_diff(&j.world, &j.local) < 1e-12);
            // Bind pose: inverse_bind * world = identity (f32 data: 1e-6 on the rotation,
            // micrometres on the translation).
            let e = j.inverse_bind * j.world - Matrix4::identity();
            assert!(
                e.fixed_view::<3, 3>(0, 0).amax() < 1e-6,
                "{file} {}: {e}",
                j.name
            );
            assert!(
                e.fixed_view::<3, 1>(0, 3).amax() < 1e-4,
                "{file} {}: {e}",
                j.name
            );
        }
        assert_eq!(skin.weights.len(), 1360);
        for w in &skin.weights {
            check_weights(w, 25);
            // README: tip joints carry no weight.
            assert!(w.iter().all(|&(j, _)| !names[j].ends_with("-tip")));
        }

        // The unit is only a scale of lengths.
        let mm = read_gltf_slice(&bytes, Units::Millimetres, &path).unwrap();
        let m = &mm.meshes[0];
        for (a, b) in m.mesh.vertices.iter().zip(&sm.mesh.vertices) {
            assert!((a.coords * 1000.0 - b.coords).norm() < 1e-9);
        }
        let (ja, jb) = (&m.skin.as_ref().unwrap().joints[3], &skin.joints[3]);
        assert!(
            (ja.local.fixed_view::<3, 3>(0, 0) - jb.local.fixed_view::<3, 3>(0, 0)).amax() < 1e-15
        );
        assert!((ja.world[(1, 3)] * 1000.0 - jb.world[(1, 3)]).abs() < 1e-9);
    }
}

/// A closed tube along +Y (8 around, 7 rings, capped), 60 mm long, radius 8 mm.
fn tube() -> TriMesh {
    let (around, rings) = (8usize, 7usize);
    let mut v = Vec::new();
    for r in 0..rings {
        for k in 0..around {
            let a = k as f64 / around as f64 * std::f64::consts::TAU;
            v.push(Point::new(8.0 * a.cos(), 10.0 * r as f64, -8.0 * a.sin()));
        }
    }
    let (bottom, top) = (v.len(), v.len() + 1);
    v.push(Point::new(0.0, 0.0, 0.0));
    v.push(Point::new(0.0, 60.0, 0.0));
    let mut f = Vec::new();
    for r in 0..rings - 1 {
        for k in 0..around {
            let (a, b) = (r * around + k, r * around + (k + 1) % around);
            let (c, d) = (a + around, b + around);
            f.push([a, b, d]);
            f.push([a, d, c]);
        }
    }
    for k in 0..around {
        f.push([bottom, (k + 1) % around, k]);
        let t = (rings - 1) * around;
        f.push([top, t + k, t + (k + 1) % around]);
    }
    TriMesh::new(v, f).unwrap()
}

/// A 4-joint chain along the tube, with rotations and a non-uniform scale in the locals so that
/// the TRS decomposition and the hierarchy are exercised; bind pose (inverse_bind = world^-1).
fn chain_skin(mesh: &TriMesh, root_parent: Matrix4<f64>) -> Skin {
    let locals = [
        Matrix4::new_translation(&Vector3::new(1.0, 0.0, 2.0))
            * Rotation3::from_euler_angles(0.1, 0.2, 0.3).to_homogeneous(),
        Matrix4::new_translation(&Vector3::new(0.0, 20.0, 0.0))
            * Rotation3::from_euler_angles(-0.2, 0.0, 0.4).to_homogeneous()
            * Matrix4::new_nonuniform_scaling(&Vector3::new(1.0, 1.1, 0.9)),
        Matrix4::new_translation(&Vector3::new(0.0, 20.0, 0.5)),
        Matrix4::new_translation(&Vector3::new(0.0, 20.0, 0.0))
            * Rotation3::from_euler_angles(0.0, 1.0, 0.0).to_homogeneous(),
    ];
    let names = ["base", "middle", "end", "tip"];
    let mut joints: Vec<SkinJoint> = Vec::new();
    for (j, local) in locals.iter().enumerate() {
        let parent = j.checked_sub(1);
        let world = match parent {
            Some(p) => joints[p].world * local,
            None => root_parent * local,
        };
        joints.push(SkinJoint {
            name: names[j].into(),
            parent,
            local: *local,
            world,
            inverse_bind: world.try_inverse().unwrap(),
        });
    }
    let weights = mesh
        .vertices
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let s = (p.y / 20.0).clamp(0.0, 2.999);
            let j = s.floor() as usize;
            let t = s - j as f64;
            let mut w = vec![(j, 1.0 - t), (j + 1, t)];
            if i % 5 == 0 {
                w.push(((j + 2) % 4, 0.05));
            }
            w.retain(|x| x.1 > 0.0);
            let sum: f64 = w.iter().map(|x| x.1).sum();
            w.iter_mut().for_each(|x| x.1 /= sum);
            w.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            w
        })
        .collect();
    Skin { joints, weights }
}

fn test_scene(root_parent: Matrix4<f64>) -> Scene {
    let mesh = tube();
    let n = mesh.n_vertices();
    let colors: Vec<[f32; 4]> = (0..n)
        .map(|i| [i as f32 / n as f32, 0.5, 1.0 - i as f32 / n as f32, 1.0])
        .collect();
    let skin = chain_skin(&mesh, root_parent);
    let normals = Some(mesh.vertex_normals());
    let mut plain = tube();
    for p in &mut plain.vertices {
        p.x += 40.0;
    }
    Scene {
        meshes: vec![
            SceneMesh {
                name: "finger".into(),
                mesh,
                normals,
                colors: Some(colors),
                skin: Some(skin),
                attributes: Vec::new(),
                morph_targets: Vec::new(),
            },
            SceneMesh {
                name: "plain tube".into(),
                mesh: plain,
                normals: None,
                colors: None,
                skin: None,
                attributes: Vec::new(),
                morph_targets: Vec::new(),
            },
        ],
        animations: Vec::new(),
    }
}

/// Read-back equality up to f32 storage: lengths to 1e-4 mm (f32 spacing at 100 mm is 8e-6),
/// unitless values to 1e-6.
fn assert_same_scene(a: &Scene, b: &Scene) {
    assert_eq!(a.meshes.len(), b.meshes.len());
    for (x, y) in a.meshes.iter().zip(&b.meshes) {
        assert_eq!(x.name, y.name);
        assert_eq!(x.mesh.faces, y.mesh.faces);
        assert_eq!(x.mesh.n_vertices(), y.mesh.n_vertices());
        for (p, q) in x.mesh.vertices.iter().zip(&y.mesh.vertices) {
            assert!((p - q).amax() < 1e-4, "{p} vs {q}");
        }
        assert_eq!(x.normals.is_some(), y.normals.is_some());
        if let (Some(n), Some(m)) = (&x.normals, &y.normals) {
            for (p, q) in n.iter().zip(m) {
                assert!((p - q).amax() < 1e-6);
            }
        }
        assert_eq!(x.colors, y.colors, "colours are f32 in and out");
        let mut xa = x.attributes.clone();
        xa.sort_by(|a, b| a.name.cmp(&b.name));
        assert_eq!(xa, y.attributes, "custom attributes are f32 in and out");
        assert_eq!(x.morph_targets.len(), y.morph_targets.len());
        for (s, t) in x.morph_targets.iter().zip(&y.morph_targets) {
            assert_eq!(s.name, t.name);
            assert!((s.weight - t.weight).abs() < 1e-6);
            assert_eq!(s.displacements.len(), t.displacements.len());
            for (p, q) in s.displacements.iter().zip(&t.displacements) {
                assert!((p - q).amax() < 1e-4, "{p} vs {q}");
            }
        }
        assert_eq!(x.skin.is_some(), y.skin.is_some());
        if let (Some(s), Some(t)) = (&x.skin, &y.skin) {
            assert_eq!(s.joints.len(), t.joints.len());
            for (j, k) in s.joints.iter().zip(&t.joints) {
                assert_eq!(j.name, k.name);
                assert_eq!(j.parent, k.parent);
                for (m, n) in [
                    (j.local, k.local),
                    (j.world, k.world),
                    (j.inverse_bind, k.inverse_bind),
                ] {
                    let e = m - n;
                    assert!(e.fixed_view::<3, 3>(0, 0).amax() < 1e-6, "{}: {e}", j.name);
                    assert!(e.fixed_view::<4, 1>(0, 3).amax() < 1e-4, "{}: {e}", j.name);
                }
            }
            assert_eq!(s.weights.len(), t.weights.len());
            for (v, w) in s.weights.iter().zip(&t.weights) {
                assert_eq!(v.len(), w.len());
                for (p, q) in v.iter().zip(w) {
                    assert_eq!(p.0, q.0);
                    assert!((p.1 - q.1).abs() < 1e-6);
                }
            }
        }
    }
}

#[test]
fn round_trip_skinned_scene() {
    let scene = test_scene(Matrix4::identity());
    let bytes = glb_bytes(&scene, Units::Metres).unwrap();
    let back = read_gltf_slice(&bytes, Units::Metres, &label()).unwrap();
    assert_same_scene(&scene, &back);

    // Layout rules checked on the raw JSON: the skinned mesh node is a root without
    // transform, positions carry min/max, every buffer view offset is 4-aligned.
    let json = glb_json(&bytes);
    let roots = json["scenes"][0]["nodes"].as_array().unwrap();
    let node0 = &json["nodes"][0];
    assert!(roots.contains(&json!(0)) && node0["skin"] == json!(0));
    for k in ["matrix", "translation", "rotation", "scale"] {
        assert!(node0.get(k).is_none());
    }
    for v in json["bufferViews"].as_array().unwrap() {
        assert_eq!(v["byteOffset"].as_u64().unwrap() % 4, 0);
    }
    let pos = &json["accessors"][json["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
        .as_u64()
        .unwrap() as usize];
    assert_eq!(pos["min"].as_array().unwrap().len(), 3);
    assert_eq!(bytes.len() % 4, 0);

    // The file unit: written in mm and read as mm gives the same scene; read as metres, 1000x.
    let mm = glb_bytes(&scene, Units::Millimetres).unwrap();
    assert_same_scene(
        &scene,
        &read_gltf_slice(&mm, Units::Millimetres, &label()).unwrap(),
    );
    let big = read_gltf_slice(&mm, Units::Metres, &label()).unwrap();
    let (p, q) = (
        scene.meshes[0].mesh.vertices[9],
        big.meshes[0].mesh.vertices[9],
    );
    assert!((p.coords * 1000.0 - q.coords).amax() < 1e-1);

    // Written through the file system, atomically.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.glb");
    write_glb(&path, &scene, Units::Metres).unwrap();
    assert_same_scene(&scene, &read_gltf(&path, Units::Metres).unwrap());
}

/// `scene` with a custom attribute on both meshes and two morph targets on the skinned one.
fn with_attributes_and_targets(mut scene: Scene) -> Scene {
    for sm in &mut scene.meshes {
        let c = crate::geometry::Point::origin();
        sm.attributes = vec![
            VertexAttribute {
                name: "_DISTANCE_MM".into(),
                values: sm
                    .mesh
                    .vertices
                    .iter()
                    .map(|p| (p - c).norm() as f32)
                    .collect(),
            },
            VertexAttribute {
                name: "_AREA".into(),
                values: (0..sm.mesh.n_vertices()).map(|i| i as f32 * 0.5).collect(),
            },
        ];
    }
    let sm = &mut scene.meshes[0];
    sm.morph_targets = vec![
        MorphTarget {
            name: "swell".into(),
            displacements: sm.mesh.vertex_normals().iter().map(|n| n * 2.0).collect(),
            weight: 0.25,
        },
        MorphTarget {
            name: "shift".into(),
            displacements: vec![Vec3::new(0.0, 3.0, -1.5); sm.mesh.n_vertices()],
            weight: 0.0,
        },
    ];
    scene
}

#[test]
fn round_trip_custom_attributes_and_morph_targets() {
    let scene = with_attributes_and_targets(test_scene(Matrix4::identity()));
    for units in [Units::Metres, Units::Millimetres] {
        let bytes = glb_bytes(&scene, units).unwrap();
        assert_same_scene(&scene, &read_gltf_slice(&bytes, units, &label()).unwrap());
    }

    // Read by the `gltf` crate, which knows nothing of ours: the target displacements in
    // metres with their required min/max, the default weights and three.js' targetNames.
    let bytes = glb_bytes(&scene, Units::Metres).unwrap();
    let (doc, buffers, _) = gltf::import_slice(&bytes).unwrap();
    let mesh = doc.meshes().next().unwrap();
    assert_eq!(mesh.weights().unwrap(), &[0.25, 0.0]);
    let extras: Value = serde_json::from_str(mesh.extras().as_ref().unwrap().get()).unwrap();
    assert_eq!(extras["targetNames"], json!(["swell", "shift"]));
    let prim = mesh.primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    let targets: Vec<Vec<[f32; 3]>> = reader
        .read_morph_targets()
        .map(|(p, _, _)| p.unwrap().collect())
        .collect();
    assert_eq!(targets.len(), 2);
    let shift = &scene.meshes[0].morph_targets[1].displacements[0];
    for d in &targets[1] {
        for k in 0..3 {
            assert!((f64::from(d[k]) * 1000.0 - shift[k]).abs() < 1e-4);
        }
    }
    let json = glb_json(&bytes);
    let t0 = json["meshes"][0]["primitives"][0]["targets"][0]["POSITION"]
        .as_u64()
        .unwrap();
    let acc = &json["accessors"][t0 as usize];
    assert!(acc["min"].is_array() && acc["max"].is_array());
    let custom = json["meshes"][1]["primitives"][0]["attributes"]["_DISTANCE_MM"]
        .as_u64()
        .unwrap();
    let acc = &json["accessors"][custom as usize];
    assert_eq!(
        (acc["type"].as_str(), acc["componentType"].as_u64()),
        (Some("SCALAR"), Some(5126))
    );

    // The spec reserves names without '_'; a wrong length is refused too.
    let mut bad = scene.clone();
    bad.meshes[1].attributes[0].name = "DISTANCE".into();
    let e = glb_bytes(&bad, Units::Metres).unwrap_err().to_string();
    assert!(
        e.contains("'plain tube'") && e.contains("'DISTANCE'") && e.contains("'_'"),
        "{e}"
    );
    let mut bad = scene.clone();
    bad.meshes[0].morph_targets[1].displacements.pop();
    let e = glb_bytes(&bad, Units::Metres).unwrap_err().to_string();
    assert!(e.contains("morph target 1 ('shift')"), "{e}");
}

#[test]
fn round_trip_root_joint_under_a_transformed_parent() {
    // The root joint's world is not its local: the writer adds a holder node, so both survive.
    let parent = Matrix4::new_translation(&Vector3::new(5.0, -3.0, 7.0))
        * Rotation3::from_euler_angles(0.5, -0.4, 0.2).to_homogeneous();
    let scene = test_scene(parent);
    let back = read_gltf_slice(
        &glb_bytes(&scene, Units::Metres).unwrap(),
        Units::Metres,
        &label(),
    )
    .unwrap();
    assert_same_scene(&scene, &back);
}

#[test]
fn round_trip_generic_hand() {
    let scene = read_gltf(&asset("right.glb"), Units::Metres).unwrap();
    let back = read_gltf_slice(
        &glb_bytes(&scene, Units::Metres).unwrap(),
        Units::Metres,
        &label(),
    )
    .unwrap();
    assert_eq!(back.meshes[0].name, "r_handMeshNode");
    assert_same_scene(&scene, &back);
}

#[test]
fn writer_rejects_unusable_scenes() {
    let good = test_scene(Matrix4::identity());
    let mut s = good.clone();
    s.meshes[0].skin.as_mut().unwrap().weights[3].clear();
    let e = glb_bytes(&s, Units::Metres).unwrap_err().to_string();
    assert!(e.contains("'finger'") && e.contains("vertex 3"), "{e}");

    let mut s = good.clone();
    s.meshes[0].skin.as_mut().unwrap().joints[2].world[(0, 3)] += 1.0;
    let e = glb_bytes(&s, Units::Metres).unwrap_err().to_string();
    assert!(e.contains("joint 2 ('end')") && e.contains("world"), "{e}");

    let mut s = good.clone();
    s.meshes[0].skin.as_mut().unwrap().joints[0].parent = Some(3);
    let e = glb_bytes(&s, Units::Metres).unwrap_err().to_string();
    assert!(e.contains("cycle"), "{e}");

    let mut s = good.clone();
    s.meshes[1].normals = Some(vec![Vec3::z(); 3]);
    let e = glb_bytes(&s, Units::Metres).unwrap_err().to_string();
    assert!(e.contains("'plain tube'") && e.contains("3 normals"), "{e}");

    let mut s = good;
    s.meshes[0].skin.as_mut().unwrap().joints[1].local[(0, 1)] += 0.5; // shear
    for j in 1..4 {
        let sk = s.meshes[0].skin.as_mut().unwrap();
        sk.joints[j].world = sk.joints[j - 1].world * sk.joints[j].local;
    }
    let e = glb_bytes(&s, Units::Metres).unwrap_err().to_string();
    assert!(e.contains("shear"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.glb");
    let e = write_glb(&path, &s, Units::Metres).unwrap_err().to_string();
    assert!(e.starts_with(&path.display().to_string()), "{e}");
    assert!(!path.exists());
}

// ---- Hand-built glTF documents for the reader's rules --------------------------------------

/// A self-contained glTF JSON: `bin` as a base64 data URI, `views` as `(offset, length)`
/// buffer views, and the rest of the document merged in.
fn gltf_doc(bin: &[u8], views: &[(usize, usize)], rest: Value) -> Vec<u8> {
    let mut doc = json!({
        "asset": { "version": "2.0" },
        "buffers": [{
            "byteLength": bin.len(),
            "uri": format!("data:application/octet-stream;base64,{}", base64_encode(bin)),
        }],
        "bufferViews": views.iter().map(|&(o, l)| json!({"buffer": 0, "byteOffset": o, "byteLength": l})).collect::<Vec<_>>(),
    });
    for (k, v) in rest.as_object().unwrap() {
        doc[k] = v.clone();
    }
    serde_json::to_vec(&doc).unwrap()
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Tetrahedron with outward faces: positive signed volume.
const TET: [f32; 12] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
const TET_FACES: [u8; 12] = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];

fn tet_doc(node: Value) -> Vec<u8> {
    let mut bin = f32_bytes(&TET);
    bin.extend_from_slice(&TET_FACES);
    gltf_doc(
        &bin,
        &[(0, 48), (48, 12)],
        json!({
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 1]},
                {"bufferView": 1, "componentType": 5121, "count": 12, "type": "SCALAR"},
            ],
            "meshes": [{"name": "tet", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
            "nodes": [node, {"name": "outer", "children": [0], "translation": [0, 0, 0.01]}],
            "scenes": [{"nodes": [1]}],
        }),
    )
}

#[test]
fn unskinned_meshes_take_the_node_world_transform() {
    // Node: translate (0.1, 0, 0) m, rotate 90 degrees about z, mirror x; outer: +0.01 m on z.
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let doc = tet_doc(
        json!({"name": "inner", "mesh": 0, "translation": [0.1, 0, 0],
                             "rotation": [0, 0, s, s], "scale": [-2, 1, 1]}),
    );
    let scene = read_gltf_slice(&doc, Units::Metres, &label()).unwrap();
    let m = &scene.meshes[0];
    assert_eq!(m.name, "inner");
    // World = T(0,0,10mm) * T(100mm,0,0) * Rz(90) * diag(-2,1,1), applied to mm positions.
    let world = Matrix4::new_translation(&Vector3::new(100.0, 0.0, 10.0))
        * Rotation3::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2)
            .to_homogeneous()
        * Matrix4::new_nonuniform_scaling(&Vector3::new(-2.0, 1.0, 1.0));
    for (k, p) in m.mesh.vertices.iter().enumerate() {
        let stored = Point::new(
            TET[3 * k] as f64,
            TET[3 * k + 1] as f64,
            TET[3 * k + 2] as f64,
        ) * 1000.0;
        assert!((world.transform_point(&stored) - p).amax() < 1e-3, "{k}");
    }
    // The mirror flips the winding back (spec 3.7.2.1), so the volume stays positive:
    // |det| = 2, tetrahedron volume (1000 mm)^3 / 6.
    let v = m.mesh.signed_volume();
    assert!((v - 2.0 * 1e9 / 6.0).abs() < 1e3, "{v}");
}

#[test]
fn strips_fans_sparse_and_weight_sets() {
    // 5 vertices; strip over all 5, fan over all 5, non-indexed.
    let pos: Vec<f32> = (0..5)
        .flat_map(|i| [i as f32, (i % 2) as f32, 0.0])
        .collect();
    let mut bin = f32_bytes(&pos); // 0..60
                                   // Sparse: replace vertex 4's position by (9, 9, 9): indices u8 [4] at 60, values at 64.
    bin.extend_from_slice(&[4, 0, 0, 0]);
    bin.extend_from_slice(&f32_bytes(&[9.0, 9.0, 9.0])); // 64..76
                                                         // JOINTS_0 u8 (5 x 4 = 20 bytes at 76), WEIGHTS_0 normalised u8 (20 at 96),
                                                         // JOINTS_1 u8 (20 at 116), WEIGHTS_1 float (80 at 136).
    let j0: Vec<u8> = (0..5).flat_map(|_| [0u8, 1, 2, 3]).collect();
    let w0: Vec<u8> = (0..5).flat_map(|v| [255u8, 51 * v as u8, 0, 0]).collect();
    let j1: Vec<u8> = (0..5).flat_map(|_| [4u8, 0, 5, 6]).collect();
    let w1: Vec<f32> = (0..5).flat_map(|_| [2.0f32, 0.5, 0.25, 0.0]).collect();
    bin.extend(j0.iter().chain(&w0).chain(&j1));
    bin.extend(f32_bytes(&w1));
    let views = [
        (0, 60),
        (60, 4),
        (64, 12),
        (76, 20),
        (96, 20),
        (116, 20),
        (136, 80),
    ];
    let skin_attrs =
        json!({"POSITION": 0, "JOINTS_0": 1, "WEIGHTS_0": 2, "JOINTS_1": 3, "WEIGHTS_1": 4});
    let doc = gltf_doc(
        &bin,
        &views,
        json!({
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 5, "type": "VEC3",
                 "min": [0, 0, 0], "max": [9, 9, 9],
                 "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5121},
                            "values": {"bufferView": 2}}},
                {"bufferView": 3, "componentType": 5121, "count": 5, "type": "VEC4"},
                {"bufferView": 4, "componentType": 5121, "normalized": true, "count": 5, "type": "VEC4"},
                {"bufferView": 5, "componentType": 5121, "count": 5, "type": "VEC4"},
                {"bufferView": 6, "componentType": 5126, "count": 5, "type": "VEC4"},
            ],
            "meshes": [{"primitives": [
                {"attributes": skin_attrs, "mode": 5},
                {"attributes": skin_attrs, "mode": 6},
                {"attributes": {"POSITION": 0}, "mode": 1},
            ]}],
            "skins": [{"joints": [1, 2, 3, 4, 5, 6, 7]}],
            "nodes": [{"mesh": 0, "skin": 0}, {"name": "j0", "children": [2]}, {"name": "j1"},
                      {"name": "j2"}, {"name": "j3"}, {"name": "j4"}, {"name": "j5"}, {"name": "j6"}],
            "scenes": [{"nodes": [0, 1, 3, 4, 5, 6, 7]}],
        }),
    );
    let scene = read_gltf_slice(&doc, Units::Millimetres, &label()).unwrap();
    let m = &scene.meshes[0];
    assert_eq!(m.name, "mesh 0");
    // Two primitives of 5 vertices merged; the LINES primitive is skipped.
    assert_eq!(m.mesh.n_vertices(), 10);
    assert_eq!(m.mesh.vertices[4], Point::new(9.0, 9.0, 9.0));
    assert_eq!(m.mesh.vertices[1], Point::new(1.0, 1.0, 0.0));
    // Spec 3.7.2.1: strip triangle i = (i, i + 1 + i%2, i + 2 - i%2); fan = (i+1, i+2, 0).
    let expect = vec![
        [0, 1, 2],
        [1, 3, 2],
        [2, 3, 4],
        [6, 7, 5],
        [7, 8, 5],
        [8, 9, 5],
    ];
    assert_eq!(m.mesh.faces, expect);
    let skin = m.skin.as_ref().unwrap();
    assert_eq!(skin.joints[1].parent, Some(0));
    assert_eq!(skin.joints[0].parent, None);
    assert_eq!(skin.weights.len(), 10);
    // Vertex v: set 0 gives joint0 1.0, joint1 v*0.2; set 1 gives joint4 2.0, joint0 0.5,
    // joint5 0.25. Merged: j0 1.5, j4 2.0, j5 0.25, j1 0.2v; top 4, normalised.
    for v in 0..5 {
        let mut want = vec![(4usize, 2.0), (0, 1.5), (5, 0.25)];
        if v > 0 {
            want.push((1, 0.2 * v as f64));
        }
        want.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let sum: f64 = want.iter().map(|x| x.1).sum();
        let got = &skin.weights[v];
        check_weights(got, 7);
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert_eq!(g.0, w.0, "vertex {v}: {got:?}");
            assert!((g.1 - w.1 / sum).abs() < 1e-6, "vertex {v}: {got:?}");
        }
        assert_eq!(skin.weights[v], skin.weights[v + 5]);
    }
}

fn read_err(doc: &[u8]) -> String {
    match read_gltf_slice(doc, Units::Metres, &label()) {
        Ok(s) => panic!("read {} meshes, expected an error", s.meshes.len()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn reader_errors_name_file_and_item() {
    let good = tet_doc(json!({"name": "inner", "mesh": 0}));
    assert!(read_gltf_slice(&good, Units::Metres, &label()).is_ok());
    let edit = |f: &dyn Fn(&mut Value)| {
        let mut v: Value = serde_json::from_slice(&good).unwrap();
        f(&mut v);
        serde_json::to_vec(&v).unwrap()
    };
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (
            edit(&|v| v["accessors"][0]["count"] = json!(5)),
            "accessor 0 (POSITION of primitive 0 of mesh 0 ('tet')) reads past buffer view 0",
        ),
        (
            edit(&|v| v["accessors"][0]["count"] = json!(4_000_000_000u64)),
            "reads past buffer view 0",
        ),
        (
            edit(&|v| {
                v["accessors"][0]
                    .as_object_mut()
                    .unwrap()
                    .remove("bufferView");
                v["accessors"][0]["count"] = json!(1u64 << 40);
            }),
            "no buffer view",
        ),
        (
            edit(&|v| v["bufferViews"][1]["byteLength"] = json!(100)),
            "buffer view 1 (bytes 48..48+100) runs past the end of buffer 0",
        ),
        (
            edit(&|v| v["buffers"][0]["byteLength"] = json!(1000)),
            "buffer 0 declares 1000 bytes",
        ),
        (
            edit(&|v| v["accessors"][0]["type"] = json!("VEC2")),
            "has type VEC2, expected VEC3",
        ),
        (
            edit(&|v| {
                v["accessors"][1]["componentType"] = json!(5126);
                v["accessors"][1]["count"] = json!(3);
            }),
            "indices must be unsigned integers",
        ),
        (
            edit(&|v| v["nodes"][1]["children"] = json!([0, 1])),
            "cycle",
        ),
        (
            edit(&|v| v["nodes"][0]["children"] = json!([0])),
            "child of both",
        ),
        (
            edit(&|v| v["meshes"][0]["primitives"][0]["mode"] = json!(0)),
            "no triangle mesh to read: skipped primitive 0 of mesh 0 ('tet') (mode Points",
        ),
        (
            edit(&|v| v["buffers"][0]["uri"] = json!("tet.bin")),
            "external file 'tet.bin'",
        ),
        (
            edit(&|v| v["asset"]["version"] = json!("1.0")),
            "asset.version",
        ),
        (
            edit(&|v| v["extensionsRequired"] = json!(["KHR_draco_mesh_compression"])),
            "KHR_draco_mesh_compression",
        ),
        (
            edit(&|v| v["nodes"][0]["rotation"] = json!([0, 0, 0, 0])),
            "node 0 ('inner') has a zero or non-finite rotation",
        ),
        (
            edit(&|v| v["nodes"][0]["translation"] = json!([1e39, 0, 0])),
            "non-finite transform",
        ),
        (b"{not json".to_vec(), "glTF JSON is not valid"),
    ];
    for (doc, want) in cases {
        let e = read_err(&doc);
        assert!(
            e.starts_with("test.glb: ") && e.contains(want),
            "got '{e}', want '{want}'"
        );
        assert!(!e.contains('\n'));
    }
    // Index out of range, named with its position.
    let mut bin = f32_bytes(&TET);
    bin.extend_from_slice(&[0, 1, 7]);
    let doc = gltf_doc(
        &bin,
        &[(0, 48), (48, 3)],
        json!({
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,1]},
                {"bufferView": 1, "componentType": 5121, "count": 3, "type": "SCALAR"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
            "nodes": [{"mesh": 0}],
        }),
    );
    let e = read_err(&doc);
    assert!(
        e.contains("index 2 is 7, but the primitive has 4 vertices"),
        "{e}"
    );
    // GLB container errors.
    let glb = compose_glb(&good, &[]).unwrap();
    assert!(read_gltf_slice(&glb, Units::Metres, &label()).is_ok());
    let e = read_err(&glb[..glb.len() - 8]);
    assert!(e.contains("GLB header: declared length"), "{e}");
    let mut bad = glb.clone();
    bad[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(read_err(&bad).contains("GLB chunk 0: declared length"));
    // A missing file names the path.
    let e = read_gltf(Path::new("/nonexistent/x.glb"), Units::Metres)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("/nonexistent/x.glb"), "{e}");
}

#[test]
fn instancing_is_read_per_node_and_capped_by_the_input_size() {
    // One mesh: 256 vertices and a u8-indexed strip of 200 000 corners (about 200 000
    // triangles from 203 kB of buffer), shown by `copies` nodes with different translations.
    let pos: Vec<f32> = (0..256)
        .flat_map(|i| [i as f32, (i % 7) as f32, (i % 3) as f32])
        .collect();
    let mut bin = f32_bytes(&pos);
    let n_idx = 200_000;
    bin.extend((0..n_idx).map(|k| (k % 256) as u8));
    let glb = |copies: usize| {
        let nodes: Vec<Value> = (0..copies)
            .map(|c| json!({"name": format!("copy {c}"), "mesh": 0, "translation": [c, 0, 0]}))
            .collect();
        let doc = json!({
            "asset": {"version": "2.0"},
            "buffers": [{"byteLength": bin.len()}],
            "bufferViews": [{"buffer": 0, "byteLength": 3072}, {"buffer": 0, "byteOffset": 3072, "byteLength": n_idx}],
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 256, "type": "VEC3", "min": [0, 0, 0], "max": [255, 6, 2]},
                {"bufferView": 1, "componentType": 5121, "count": n_idx, "type": "SCALAR"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 5}]}],
            "nodes": nodes,
        });
        compose_glb(&serde_json::to_vec(&doc).unwrap(), &bin).unwrap()
    };
    let scene = read_gltf_slice(&glb(3), Units::Millimetres, &label()).unwrap();
    assert_eq!(scene.meshes.len(), 3);
    for (c, m) in scene.meshes.iter().enumerate() {
        assert_eq!(m.name, format!("copy {c}"));
        assert_eq!(m.mesh.n_faces(), n_idx - 2);
        assert_eq!(m.mesh.faces, scene.meshes[0].mesh.faces);
        assert_eq!(m.mesh.vertices[5].x, 5.0 + c as f64);
    }
    // 12 copies are 2.4 M triangles from a 0.2 MB file: refused, naming the node.
    let e = read_err(&glb(12));
    assert!(
        e.contains("('copy ") && e.contains("instantiates meshes so often"),
        "{e}"
    );
}

#[test]
fn external_buffers_resolve_next_to_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut bin = f32_bytes(&TET);
    bin.extend_from_slice(&TET_FACES);
    std::fs::write(dir.path().join("tet data.bin"), &bin).unwrap();
    let mut doc: Value = serde_json::from_slice(&tet_doc(json!({"mesh": 0}))).unwrap();
    doc["buffers"][0]["uri"] = json!("tet%20data.bin");
    let path = dir.path().join("tet.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = read_gltf(&path, Units::Metres).unwrap();
    assert_eq!(scene.meshes[0].mesh.n_faces(), 4);
    doc["buffers"][0]["uri"] = json!("missing.bin");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let e = read_gltf(&path, Units::Metres).unwrap_err().to_string();
    assert!(
        e.contains("buffer 0: cannot read") && e.contains("missing.bin"),
        "{e}"
    );
}

/// Writes sample GLBs for the Khronos validator into `$ERGOHAND_GLTF_SAMPLES` (see
/// `validation/tools/gltf_validate.mjs`); ignored by default because it only exports files.
#[test]
#[ignore]
fn export_validator_samples() {
    let dir =
        PathBuf::from(std::env::var("ERGOHAND_GLTF_SAMPLES").expect("set ERGOHAND_GLTF_SAMPLES"));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = test_scene(Matrix4::identity());
    write_glb(&dir.join("skinned_colours.glb"), &scene, Units::Metres).unwrap();
    let unskinned = Scene {
        meshes: vec![scene.meshes[1].clone()],
        animations: Vec::new(),
    };
    write_glb(&dir.join("unskinned.glb"), &unskinned, Units::Metres).unwrap();
    let mut coloured = unskinned.clone();
    coloured.meshes[0].colors = Some(vec![
        [0.2, 0.4, 0.6, 1.0];
        coloured.meshes[0].mesh.n_vertices()
    ]);
    coloured.meshes[0].normals = Some(coloured.meshes[0].mesh.vertex_normals());
    write_glb(
        &dir.join("unskinned_colours_normals.glb"),
        &coloured,
        Units::Metres,
    )
    .unwrap();
    let held = test_scene(Matrix4::new_translation(&Vector3::new(5.0, -3.0, 7.0)));
    write_glb(&dir.join("skinned_held_root.glb"), &held, Units::Metres).unwrap();
    let hand = read_gltf(&asset("right.glb"), Units::Metres).unwrap();
    write_glb(&dir.join("generic_hand_right.glb"), &hand, Units::Metres).unwrap();
    let extended = with_attributes_and_targets(test_scene(Matrix4::identity()));
    write_glb(
        &dir.join("attributes_morph_targets.glb"),
        &extended,
        Units::Metres,
    )
    .unwrap();
}

// ---- Hostile input -------------------------------------------------------------------------

fn small_glb() -> Vec<u8> {
    // A few faces keep each case fast while every kind of accessor is present.
    let mut scene = test_scene(Matrix4::identity());
    let sm = &mut scene.meshes[0];
    sm.mesh.faces.truncate(6);
    scene.meshes.truncate(1);
    glb_bytes(&scene, Units::Metres).unwrap()
}

/// The reader without its catch_unwind guard, so that a panic fails the property.
fn read_unguarded(bytes: &[u8]) -> Result<Scene> {
    read::read_scene(bytes, Units::Metres, &label(), None)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn truncated_glb_never_panics(cut in 0usize..4000) {
        let glb = small_glb();
        let cut = cut.min(glb.len());
        let r = read_unguarded(&glb[..cut]);
        if cut < glb.len() {
            prop_assert!(r.is_err());
        }
    }

    #[test]
    fn mutated_glb_never_panics(edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..8)) {
        let mut glb = small_glb();
        let n = glb.len();
        for (at, b) in edits {
            glb[at % n] = b;
        }
        let _ = read_unguarded(&glb);
    }

    #[test]
    fn mutated_json_numbers_never_panic(edits in proptest::collection::vec((any::<usize>(), 0u8..10), 1..6)) {
        // Replacing digits by digits keeps the JSON well formed, so the edits reach the
        // accessor, view, index and count checks rather than the JSON parser.
        let mut glb = small_glb();
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        let digits: Vec<usize> = (20..20 + json_len).filter(|&i| glb[i].is_ascii_digit()).collect();
        for (at, d) in edits {
            glb[digits[at % digits.len()]] = b'0' + d;
        }
        let _ = read_unguarded(&glb);
    }
}

/// Rotations about z by `deg` degrees.
fn about_z(deg: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), deg.to_radians())
}

/// Consecutive stored quaternions of opposite sign would make LINEAR slerp turn the long way:
/// each output is the same rotation as its input, and neighbours have a non-negative dot.
#[test]
fn sign_continuous_keeps_rotations_and_takes_the_short_way() {
    let input: Vec<UnitQuaternion<f64>> = [0.0, 100.0, 170.0, 190.0, 260.0, 350.0, 370.0]
        .iter()
        .enumerate()
        .map(|(k, &d)| {
            let q = about_z(d);
            // Flip every other one by hand: the same rotation, the other sign.
            if k % 2 == 1 {
                UnitQuaternion::new_unchecked(-q.into_inner())
            } else {
                q
            }
        })
        .collect();
    let out = sign_continuous(&input);
    assert_eq!(out.len(), input.len());
    for (a, b) in input.iter().zip(&out) {
        assert!(a.angle_to(b) < 1e-12);
    }
    for w in out.windows(2) {
        assert!(w[0].coords.dot(&w[1].coords) >= 0.0, "{w:?}");
    }
    assert!(sign_continuous(&[]).is_empty());
}

/// An animation on a joint and on an unskinned mesh node: written as LINEAR samplers whose
/// time input has min/max and is shared by channels with the same times, read back with the
/// same targets, times, translations (in mm) and rotations (sign-continuous in the file).
#[test]
fn animation_round_trips() {
    let mut scene = test_scene(Matrix4::identity());
    let times = vec![0.0, 0.1, 0.25, 0.5];
    let mut rotations: Vec<UnitQuaternion<f64>> = [0.0, 120.0, 200.0, 300.0]
        .iter()
        .map(|&d| about_z(d))
        .collect();
    // The same rotation with the other sign: the writer must flip it back.
    rotations[2] = UnitQuaternion::new_unchecked(-rotations[2].into_inner());
    let translations: Vec<Vec3> = (0..4)
        .map(|k| Vec3::new(10.0 * k as f64, -3.5, 250.0))
        .collect();
    scene.animations.push(Animation {
        name: "move".into(),
        channels: vec![
            Channel {
                target: AnimationTarget::Joint { mesh: 0, joint: 1 },
                times: times.clone(),
                values: Keyframes::Rotation(rotations.clone()),
            },
            Channel {
                target: AnimationTarget::Mesh(1),
                times: times.clone(),
                values: Keyframes::Translation(translations.clone()),
            },
            Channel {
                target: AnimationTarget::Mesh(1),
                times: vec![0.0, 1.0],
                values: Keyframes::Rotation(vec![about_z(0.0), about_z(90.0)]),
            },
        ],
    });
    let bytes = glb_bytes(&scene, Units::Metres).unwrap();

    let doc = glb_json(&bytes);
    let anim = &doc["animations"][0];
    let samplers = anim["samplers"].as_array().unwrap();
    assert_eq!(samplers.len(), 3);
    assert_eq!(samplers[0]["input"], samplers[1]["input"]);
    assert_ne!(samplers[0]["input"], samplers[2]["input"]);
    for s in samplers {
        assert_eq!(s["interpolation"], "LINEAR");
        let acc = &doc["accessors"][s["input"].as_u64().unwrap() as usize];
        assert_eq!(acc["type"], "SCALAR");
        assert!(acc["min"].is_array() && acc["max"].is_array(), "{acc}");
    }
    let input = &doc["accessors"][samplers[0]["input"].as_u64().unwrap() as usize];
    assert_eq!(input["min"][0].as_f64(), Some(0.0));
    assert_eq!(input["max"][0].as_f64(), Some(0.5));
    // Joint 1 of the skin is the node after the mesh node and joint 0.
    assert_eq!(anim["channels"][0]["target"]["node"], 2);
    assert_eq!(anim["channels"][0]["target"]["path"], "rotation");
    assert_eq!(anim["channels"][1]["target"]["path"], "translation");

    let back = read_gltf_slice(&bytes, Units::Metres, Path::new("anim.glb")).unwrap();
    assert_eq!(back.animations.len(), 1);
    let a = &back.animations[0];
    assert_eq!(a.name, "move");
    assert_eq!(a.channels.len(), 3);
    for (x, y) in a.channels.iter().zip(&scene.animations[0].channels) {
        assert_eq!(x.target, y.target);
        assert_eq!(x.times.len(), y.times.len());
        for (s, t) in x.times.iter().zip(&y.times) {
            assert!((s - t).abs() < 1e-7);
        }
    }
    let Keyframes::Rotation(r) = &a.channels[0].values else {
        panic!("rotation expected")
    };
    for (p, q) in r.iter().zip(&rotations) {
        assert!(p.angle_to(q) < 1e-6);
    }
    assert!(rotations[1].coords.dot(&rotations[2].coords) < 0.0);
    for w in r.windows(2) {
        assert!(w[0].coords.dot(&w[1].coords) >= 0.0);
    }
    let Keyframes::Translation(t) = &a.channels[1].values else {
        panic!("translation expected")
    };
    for (p, q) in t.iter().zip(&translations) {
        assert!((p - q).norm() < 1e-4, "{p} vs {q}");
    }
}

/// What glTF cannot hold is refused with a message naming the channel.
#[test]
fn animation_errors_name_the_channel() {
    let base = test_scene(Matrix4::identity());
    let chan = |target, times: Vec<f64>, n: usize| Channel {
        target,
        times,
        values: Keyframes::Translation(vec![Vec3::zeros(); n]),
    };
    let cases: Vec<(Vec<Channel>, &str)> = vec![
        (vec![], "no channel"),
        (
            vec![chan(AnimationTarget::Mesh(0), vec![0.0], 1)],
            "skinned mesh",
        ),
        (
            vec![chan(AnimationTarget::Mesh(1), vec![0.0, 0.0], 2)],
            "not after",
        ),
        (
            vec![chan(AnimationTarget::Mesh(1), vec![-1.0, 0.0], 2)],
            ">= 0",
        ),
        (
            vec![chan(AnimationTarget::Mesh(1), vec![0.0, 1.0], 3)],
            "3 values for 2 times",
        ),
        (
            vec![chan(
                AnimationTarget::Joint { mesh: 1, joint: 0 },
                vec![0.0],
                1,
            )],
            "no skin",
        ),
        (
            vec![
                chan(AnimationTarget::Mesh(1), vec![0.0], 1),
                chan(AnimationTarget::Mesh(1), vec![1.0], 1),
            ],
            "second channel",
        ),
    ];
    for (channels, want) in cases {
        let mut scene = base.clone();
        scene.animations.push(Animation {
            name: "a".into(),
            channels,
        });
        let e = glb_bytes(&scene, Units::Metres).unwrap_err().to_string();
        assert!(e.contains(want) && e.contains("animation 0"), "{want}: {e}");
    }
}
