//! Writing [`Animation`]s (glTF 2.0 spec 3.11 "Animations"): per channel one sampler, LINEAR,
//! whose input is the keyframe times (seconds, `f32` SCALAR with `min`/`max`, which the spec
//! requires of sampler inputs) and whose output is the node's local `translation` (VEC3, file
//! units) or `rotation` (VEC4 unit quaternion, x y z w). Channels with identical times share
//! one input accessor.

use super::buffer::{f32s, Bin, FLOAT};
use super::{sign_continuous, AnimationTarget, Channel, Keyframes, Scene};
use crate::error::{Error, Result};
use serde_json::{json, Map, Value};
use std::collections::HashSet;

/// The node indices the writer gave a scene: per [`Scene::meshes`] entry its mesh node, and
/// for a skinned one the node of joint 0 and the joint count (joint `j` is node `base + j`).
#[derive(Default)]
pub(super) struct NodeMap {
    pub(super) mesh: Vec<usize>,
    pub(super) joints: Vec<Option<(usize, usize)>>,
}

/// The glTF `animations` array of `scene` (empty when it has none), accessors appended to
/// `bin`. Fails ([`Error::Invalid`], naming the animation and channel) on an animation
/// without channels, a target out of range or on a skinned mesh node (spec 3.7.3: its
/// transform is ignored), two channels on the same node and property (the spec forbids it),
/// times that are empty, negative, not finite or not strictly increasing in `f32`, a value
/// count that differs from the time count, or a value that is not finite.
pub(super) fn write_animations(
    bin: &mut Bin,
    scene: &Scene,
    nodes: &NodeMap,
    mm: f64,
) -> Result<Vec<Value>> {
    let mut inputs: Vec<(Vec<f32>, usize)> = Vec::new();
    let mut out = Vec::with_capacity(scene.animations.len());
    for (a, anim) in scene.animations.iter().enumerate() {
        let what = |c: usize| format!("animation {a} ('{}') channel {c}", anim.name);
        if anim.channels.is_empty() {
            return Err(Error::invalid(format!(
                "animation {a} ('{}') has no channel; glTF needs at least one",
                anim.name
            )));
        }
        let mut seen = HashSet::new();
        let mut samplers = Vec::with_capacity(anim.channels.len());
        let mut channels = Vec::with_capacity(anim.channels.len());
        for (c, ch) in anim.channels.iter().enumerate() {
            let bad = |msg: String| Error::invalid(format!("{}: {msg}", what(c)));
            let node = target_node(scene, nodes, ch.target).map_err(bad)?;
            let path = match ch.values {
                Keyframes::Translation(_) => "translation",
                Keyframes::Rotation(_) => "rotation",
            };
            if !seen.insert((node, path)) {
                return Err(bad(format!(
                    "a second channel on the {path} of the same node; the spec allows one"
                )));
            }
            let input = time_input(bin, &mut inputs, ch).map_err(bad)?;
            let output = keyframe_output(bin, &ch.values, mm).map_err(bad)?;
            channels.push(json!({
                "sampler": samplers.len(),
                "target": { "node": node, "path": path },
            }));
            samplers.push(json!({
                "input": input,
                "output": output,
                "interpolation": "LINEAR",
            }));
        }
        out.push(json!({
            "name": anim.name,
            "channels": channels,
            "samplers": samplers,
        }));
    }
    Ok(out)
}

/// The node index of `target`, or why there is none.
fn target_node(
    scene: &Scene,
    nodes: &NodeMap,
    target: AnimationTarget,
) -> std::result::Result<usize, String> {
    let n = scene.meshes.len();
    match target {
        AnimationTarget::Mesh(m) if m >= n => {
            Err(format!("targets mesh {m}, but the scene has {n}"))
        }
        AnimationTarget::Mesh(m) if scene.meshes[m].skin.is_some() => Err(format!(
            "targets the node of skinned mesh '{}', whose transform glTF ignores (spec 3.7.3); \
             animate its joints",
            scene.meshes[m].name
        )),
        AnimationTarget::Mesh(m) => Ok(nodes.mesh[m]),
        AnimationTarget::Joint { mesh, .. } if mesh >= n => Err(format!(
            "targets a joint of mesh {mesh}, but the scene has {n}"
        )),
        AnimationTarget::Joint { mesh, joint } => match nodes.joints[mesh] {
            Some((base, count)) if joint < count => Ok(base + joint),
            Some((_, count)) => Err(format!(
                "targets joint {joint} of mesh '{}', whose skin has {count}",
                scene.meshes[mesh].name
            )),
            None => Err(format!(
                "targets joint {joint} of mesh '{}', which has no skin",
                scene.meshes[mesh].name
            )),
        },
    }
}

/// The input accessor of `ch`: its times checked (spec 3.11: `t[0] >= 0`, strictly
/// increasing, here in the stored `f32`, and as many as values) and written with `min`/`max`,
/// or the accessor of an earlier channel with the same times.
fn time_input(
    bin: &mut Bin,
    inputs: &mut Vec<(Vec<f32>, usize)>,
    ch: &Channel,
) -> std::result::Result<usize, String> {
    let n = ch.times.len();
    if n == 0 {
        return Err("has no keyframe".into());
    }
    if ch.values.len() != n {
        return Err(format!("has {} values for {n} times", ch.values.len()));
    }
    let times: Vec<f32> = ch.times.iter().map(|&t| t as f32).collect();
    for (k, &t) in times.iter().enumerate() {
        if !(t.is_finite() && t >= 0.0) {
            return Err(format!("time {k} is {t}; times must be finite and >= 0"));
        }
        if k > 0 && t <= times[k - 1] {
            return Err(format!(
                "time {k} ({t} s) is not after time {} ({} s) in f32",
                k - 1,
                times[k - 1]
            ));
        }
    }
    if let Some((_, a)) = inputs.iter().find(|(t, _)| *t == times) {
        return Ok(*a);
    }
    let mut extra = Map::new();
    extra.insert("min".into(), json!([f64::from(times[0])]));
    extra.insert("max".into(), json!([f64::from(times[n - 1])]));
    let a = bin.accessor(
        &f32s(times.iter().copied()),
        FLOAT,
        n,
        "SCALAR",
        None,
        extra,
    );
    inputs.push((times, a));
    Ok(a)
}

/// The output accessor of `values`: translations divided by `mm` (mm to file units, as the
/// node translations), rotations made sign-continuous ([`sign_continuous`]) and normalised in
/// `f32` (the validator checks unit length at `f32` precision).
fn keyframe_output(
    bin: &mut Bin,
    values: &Keyframes,
    mm: f64,
) -> std::result::Result<usize, String> {
    let (data, count, ty) = match values {
        Keyframes::Translation(v) => {
            let mut data = Vec::with_capacity(v.len() * 3);
            for (k, t) in v.iter().enumerate() {
                let f = t.map(|x| (x / mm) as f32);
                if !f.iter().all(|x| x.is_finite()) {
                    return Err(format!("translation {k} is not finite in f32"));
                }
                data.extend_from_slice(f.as_slice());
            }
            (data, v.len(), "VEC3")
        }
        Keyframes::Rotation(v) => {
            let mut data = Vec::with_capacity(v.len() * 4);
            for (k, q) in sign_continuous(v).iter().enumerate() {
                let c = q.coords.map(|x| x as f32);
                let n = c.norm();
                if !(n.is_finite() && n > 0.5) {
                    return Err(format!("rotation {k} is not a finite unit quaternion"));
                }
                data.extend_from_slice((c / n).as_slice());
            }
            (data, v.len(), "VEC4")
        }
    };
    Ok(bin.accessor(&f32s(data), FLOAT, count, ty, None, Map::new()))
}
