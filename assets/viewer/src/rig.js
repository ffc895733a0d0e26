// The toolkit's posing, ported to the page: forward kinematics of the link model and
// dual-quaternion skinning, the same arithmetic as ergohand's
// `skeleton::forward_kinematics::link_transforms` and `pose::SkinBinding::dual_quaternion`
// (Kavan et al. 2008, algorithm 1, with the antipodality check against the point's dominant
// link). validation/tools/check_view.mjs --rig checks that the page and the toolkit agree.
//
// Lengths are millimetres, angles degrees at the interface, quaternions [w, x, y, z].

// Hamilton product a * b.
function qmul(a, b) {
  return [
    a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
    a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
    a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
    a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
  ];
}

// The rotation of v by the unit quaternion q: v + 2 w (u × v) + 2 u × (u × v).
function qrot(q, v) {
  const [w, x, y, z] = q;
  const cx = y * v[2] - z * v[1], cy = z * v[0] - x * v[2], cz = x * v[1] - y * v[0];
  const ccx = y * cz - z * cy, ccy = z * cx - x * cz, ccz = x * cy - y * cx;
  return [v[0] + 2 * (w * cx + ccx), v[1] + 2 * (w * cy + ccy), v[2] + 2 * (w * cz + ccz)];
}

function axisAngle(axis, radians) {
  const h = radians / 2, s = Math.sin(h);
  return [Math.cos(h), axis[0] * s, axis[1] * s, axis[2] * s];
}

// Rigid motions {q, t}: p -> q p q* + t. a * b applies b first.
function compose(a, b) {
  const r = qrot(a.q, b.t);
  return { q: qmul(a.q, b.q), t: [r[0] + a.t[0], r[1] + a.t[1], r[2] + a.t[2]] };
}

const RAD = Math.PI / 180;

// The arrays of the rig's binary element (little endian; see the Rust side's RigEntry).
export function decodeRig(rig, bytes) {
  const buf = bytes.buffer, base = bytes.byteOffset;
  const view = (Type, [offset, count]) => {
    const at = base + offset;
    if (at % Type.BYTES_PER_ELEMENT === 0) return new Type(buf, at, count);
    return new Type(bytes.slice(offset, offset + count * Type.BYTES_PER_ELEMENT).buffer);
  };
  const out = {
    n: rig.vertices,
    rest: view(Float32Array, rig.rest),
    shown: view(Float32Array, rig.shown),
    faces: view(Uint32Array, rig.faces),
    offsets: view(Uint32Array, rig.offsets),
    weights: view(Float32Array, rig.weights),
    links: view(Uint8Array, rig.links),
  };
  if (out.rest.length !== 3 * out.n || out.shown.length !== 3 * out.n || out.offsets.length !== out.n + 1) {
    throw new Error("the rig's arrays do not match its vertex count");
  }
  if (out.links.length !== out.weights.length || out.offsets[out.n] !== out.weights.length) {
    throw new Error("the rig's weights do not match their offsets");
  }
  return out;
}

// Every link's motion from the reference posture, for `deg[j]` = the angles (degrees) of
// rig.joints[j]: the forearm moves by rig.root, and each joint's child link by its parent's
// motion times the joint's rotation about its reference centre (joints come parents first).
export function linkTransforms(rig, deg) {
  const t = rig.link_names.map(() => ({ q: [1, 0, 0, 0], t: [0, 0, 0] }));
  t[0] = { q: rig.root.rotation.slice(), t: rig.root.translation.slice() };
  rig.joints.forEach((j, k) => {
    let r = [1, 0, 0, 0];
    j.axes.forEach((axis, d) => {
      r = qmul(r, axisAngle(axis, (deg[k][d] || 0) * RAD));
    });
    const rc = qrot(r, j.centre);
    const about = { q: r, t: [j.centre[0] - rc[0], j.centre[1] - rc[1], j.centre[2] - rc[2]] };
    t[j.child] = compose(t[j.parent], about);
  });
  return t;
}

// Dual-quaternion skinning of the rest skin by the links' motions into `out` (xyz per vertex).
export function dualQuaternionSkin(arrays, transforms, out) {
  const dq = transforms.map(({ q, t }) => {
    const d = qmul([0, t[0], t[1], t[2]], q);
    return { real: q, dual: [d[0] / 2, d[1] / 2, d[2] / 2, d[3] / 2] };
  });
  const { n, rest, offsets, weights, links } = arrays;
  const real = [0, 0, 0, 0], dual = [0, 0, 0, 0];
  for (let i = 0; i < n; i++) {
    const px = rest[3 * i], py = rest[3 * i + 1], pz = rest[3 * i + 2];
    const a = offsets[i], b = offsets[i + 1];
    out[3 * i] = px; out[3 * i + 1] = py; out[3 * i + 2] = pz;
    if (a === b) continue;
    // the pivot: the dominant link (the last of equal largest weights, as the toolkit's max_by)
    let dom = a;
    for (let k = a + 1; k < b; k++) if (weights[k] >= weights[dom]) dom = k;
    const pivot = dq[links[dom]].real;
    real[0] = real[1] = real[2] = real[3] = 0;
    dual[0] = dual[1] = dual[2] = dual[3] = 0;
    for (let k = a; k < b; k++) {
      const d = dq[links[k]];
      const r = d.real;
      const dot = r[0] * pivot[0] + r[1] * pivot[1] + r[2] * pivot[2] + r[3] * pivot[3];
      const w = dot < 0 ? -weights[k] : weights[k];
      for (let c = 0; c < 4; c++) {
        real[c] += r[c] * w;
        dual[c] += d.dual[c] * w;
      }
    }
    const norm = Math.hypot(real[0], real[1], real[2], real[3]);
    if (norm < 1e-12) continue;
    const w0 = real[0] / norm, x0 = real[1] / norm, y0 = real[2] / norm, z0 = real[3] / norm;
    const we = dual[0] / norm, xe = dual[1] / norm, ye = dual[2] / norm, ze = dual[3] / norm;
    // rotated = p + 2 (w0 (v0 × p) + v0 × (v0 × p))
    const cx = y0 * pz - z0 * py, cy = z0 * px - x0 * pz, cz = x0 * py - y0 * px;
    const ccx = y0 * cz - z0 * cy, ccy = z0 * cx - x0 * cz, ccz = x0 * cy - y0 * cx;
    // t = 2 (w0 ve - we v0 + v0 × ve)
    const tx = 2 * (w0 * xe - we * x0 + (y0 * ze - z0 * ye));
    const ty = 2 * (w0 * ye - we * y0 + (z0 * xe - x0 * ze));
    const tz = 2 * (w0 * ze - we * z0 + (x0 * ye - y0 * xe));
    out[3 * i] = px + 2 * (w0 * cx + ccx) + tx;
    out[3 * i + 1] = py + 2 * (w0 * cy + ccy) + ty;
    out[3 * i + 2] = pz + 2 * (w0 * cz + ccz) + tz;
  }
  return out;
}
