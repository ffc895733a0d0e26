// ergohand view.html: the browser side of the self-contained 3-D viewer page.
//
// Built by build.sh (esbuild) into viewer.bundle.js, one minified IIFE that the Rust side
// inlines into view-template.html. The page carries everything it needs: the data contract
// (JSON in the script element with id ergohand-view-data) and each GLB as base64 in
// script elements with ids ergohand-glb-N (type application/octet-stream). No network, no eval.
// README.md beside this folder describes the contract.

import {
  AnimationMixer,
  Box3,
  BufferAttribute,
  BufferGeometry,
  Color,
  DirectionalLight,
  HemisphereLight,
  Mesh,
  MeshBasicMaterial,
  MeshStandardMaterial,
  PerspectiveCamera,
  Raycaster,
  Scene,
  SphereGeometry,
  Sphere,
  Vector2,
  Vector3,
  WebGLRenderer,
} from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { decodeRig, dualQuaternionSkin, linkTransforms } from "./rig.js";

const T0 = performance.now();
const BACKGROUND = "#f3f4f6";
const BACKGROUND_RGB = [0xf3, 0xf4, 0xf6];
const MARKER_COLOUR = 0xe6007e;
const SKIN_COLOUR = 0xd9b8a0;

// matplotlib's viridis at 0, 0.1, ..., 1 (sRGB), enough stops for a CSS gradient.
const COLORMAPS = {
  viridis: [
    "#440154", "#482475", "#414487", "#355f8d", "#2a788e", "#21918c",
    "#22a884", "#44bf70", "#7ad151", "#bddf26", "#fde725",
  ],
};

// glTF attribute semantics that three's GLTFLoader renames; any other attribute (custom ones
// start with "_", e.g. "_DISTANCE_MM") becomes its name in lower case ("_distance_mm").
const GLTF_ATTRIBUTES = {
  POSITION: "position", NORMAL: "normal", TANGENT: "tangent", TEXCOORD_0: "uv",
  TEXCOORD_1: "uv1", TEXCOORD_2: "uv2", TEXCOORD_3: "uv3", COLOR_0: "color",
  WEIGHTS_0: "skinWeight", JOINTS_0: "skinIndex",
};
const threeAttributeName = (gltfName) => GLTF_ATTRIBUTES[gltfName] || String(gltfName).toLowerCase();

// ---------------------------------------------------------------------------------------------
// small DOM helpers (text only: nothing from the data is ever parsed as HTML)

function el(tag, props, ...children) {
  const e = document.createElement(tag);
  if (props) {
    for (const [k, v] of Object.entries(props)) {
      if (k === "class") e.className = v;
      else if (k === "style") e.style.cssText = v;
      else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
      else e.setAttribute(k, v);
    }
  }
  for (const c of children) {
    if (c === null || c === undefined || c === false) continue;
    e.append(c instanceof Node ? c : String(c));
  }
  return e;
}

const byId = (id) => document.getElementById(id);

function fmt(v, digits = 4) {
  if (typeof v !== "number") return String(v);
  if (!Number.isFinite(v)) return String(v);
  if (v === 0) return "0";
  return String(Number(v.toPrecision(digits)));
}

// ---------------------------------------------------------------------------------------------
// data

function readData() {
  const s = byId("ergohand-view-data");
  if (!s) throw new Error('no element with id "ergohand-view-data" (the view data) in the page');
  const data = JSON.parse(s.textContent);
  if (!data || typeof data !== "object") throw new Error("the view data is not a JSON object");
  if (!Array.isArray(data.meshes)) data.meshes = [];
  return data;
}

function decodeBase64(text) {
  if (typeof Uint8Array.fromBase64 === "function") {
    try {
      return Uint8Array.fromBase64(text.trim());
    } catch (_) {
      /* fall through to atob, which forgives more whitespace */
    }
  }
  const bin = atob(text.replace(/\s+/g, ""));
  const n = bin.length;
  const out = new Uint8Array(n);
  for (let i = 0; i < n; i++) out[i] = bin.charCodeAt(i);
  return out;
}

function parseGlb(loader, bytes) {
  const buffer = bytes.byteOffset === 0 && bytes.byteLength === bytes.buffer.byteLength
    ? bytes.buffer
    : bytes.slice().buffer;
  return new Promise((resolve, reject) => loader.parse(buffer, "", resolve, reject));
}

// ---------------------------------------------------------------------------------------------
// geometry

// Smooth per-vertex normals, area-weighted. Vertices are welded by position first, so a mesh
// written as a triangle soup (one vertex per corner, as STL parts are) is smooth too.
function smoothNormals(geometry) {
  const pos = geometry.getAttribute("position");
  const index = geometry.getIndex();
  const nv = pos.count;
  const nt = index ? index.count / 3 : nv / 3;
  if (index && nv <= nt) {
    // shared vertices already (a closed welded mesh has about half as many vertices as
    // triangles): three's own routine is exact and quick
    geometry.computeVertexNormals();
    return;
  }
  // weld: id of the first vertex at each position, quantised to 1e-5 of the mesh's size (the
  // corners of a soup that meet are bit-identical); numeric keys below 2^51 for a quick Map
  geometry.computeBoundingBox();
  const bb = geometry.boundingBox;
  const q = Math.max(bb.max.x - bb.min.x, bb.max.y - bb.min.y, bb.max.z - bb.min.z, 1e-30) * 1e-5;
  const K = 131072; // 2^17 > 1e5 + 1
  const canon = new Uint32Array(nv);
  const seen = new Map();
  const v = new Vector3();
  for (let i = 0; i < nv; i++) {
    v.fromBufferAttribute(pos, i);
    const key = (Math.round((v.x - bb.min.x) / q) * K + Math.round((v.y - bb.min.y) / q)) * K + Math.round((v.z - bb.min.z) / q);
    const first = seen.get(key);
    if (first === undefined) {
      seen.set(key, i);
      canon[i] = i;
    } else {
      canon[i] = first;
    }
  }
  const acc = new Float32Array(nv * 3);
  const a = new Vector3(), b = new Vector3(), c = new Vector3(), ab = new Vector3(), ac = new Vector3();
  const idx = index ? index.array : null;
  for (let t = 0; t < nt; t++) {
    const i0 = idx ? idx[3 * t] : 3 * t, i1 = idx ? idx[3 * t + 1] : 3 * t + 1, i2 = idx ? idx[3 * t + 2] : 3 * t + 2;
    a.fromBufferAttribute(pos, i0); b.fromBufferAttribute(pos, i1); c.fromBufferAttribute(pos, i2);
    ab.subVectors(b, a); ac.subVectors(c, a); ab.cross(ac); // length = 2 * area
    for (let k = 0; k < 3; k++) {
      const w = 3 * canon[k === 0 ? i0 : k === 1 ? i1 : i2];
      acc[w] += ab.x; acc[w + 1] += ab.y; acc[w + 2] += ab.z;
    }
  }
  const normals = new Float32Array(nv * 3);
  for (let i = 0; i < nv; i++) {
    const v = canon[i];
    const x = acc[3 * v], y = acc[3 * v + 1], z = acc[3 * v + 2];
    const l = Math.hypot(x, y, z) || 1;
    normals[3 * i] = x / l; normals[3 * i + 1] = y / l; normals[3 * i + 2] = z / l;
  }
  geometry.setAttribute("normal", new BufferAttribute(normals, 3));
}

function triangleCount(geometry) {
  const index = geometry.getIndex();
  return Math.floor((index ? index.count : geometry.getAttribute("position").count) / 3);
}

// Names an object is known by: its own (three sanitises them: spaces become "_") and the
// original glTF node and mesh names from the parser's associations.
function originalNames(object, gltf) {
  const names = [];
  if (object.name) names.push(object.name);
  const assoc = gltf.parser.associations.get(object);
  const json = gltf.parser.json;
  if (assoc) {
    if (assoc.nodes !== undefined && json.nodes && json.nodes[assoc.nodes]) names.push(json.nodes[assoc.nodes].name);
    if (assoc.meshes !== undefined && json.meshes && json.meshes[assoc.meshes]) names.push(json.meshes[assoc.meshes].name);
  }
  return names.filter((n) => typeof n === "string" && n !== "");
}

function nodeName(mesh, gltf) {
  const json = gltf.parser.json;
  for (let o = mesh; o; o = o.parent) {
    const assoc = gltf.parser.associations.get(o);
    if (assoc && assoc.nodes !== undefined && json.nodes[assoc.nodes] && json.nodes[assoc.nodes].name) {
      return json.nodes[assoc.nodes].name;
    }
    if (o === gltf.scene) break;
  }
  const n = originalNames(mesh, gltf);
  return n.length ? n[n.length - 1] : "mesh";
}

function isPart(mesh, gltf, partNames) {
  if (partNames.size === 0) return false;
  for (let o = mesh; o; o = o.parent) {
    for (const n of originalNames(o, gltf)) if (partNames.has(n)) return true;
    if (o === gltf.scene) break;
  }
  return false;
}

function visibleInScene(o) {
  for (; o; o = o.parent) if (!o.visible) return false;
  return true;
}

// ---------------------------------------------------------------------------------------------
// the viewer

class Viewer {
  constructor(data) {
    this.data = data;
    this.scale = ({ m: 1000, cm: 10, mm: 1 })[data.glb_units || "m"] ?? 1000;
    this.meshes = []; // { mesh, gltf, name, part, value }
    this.parts = [];
    this.mixers = [];
    this.clipDuration = 0;
    this.time = 0;
    this.playing = false;
    this.renderQueued = false;
    this.timings = { decode: 0, parse: 0, normals: 0 }; // ms

    this.host = byId("eh-view");
    this.status = byId("eh-status");

    this.renderer = new WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.host.prepend(this.renderer.domElement);

    this.scene = new Scene();
    this.scene.background = new Color(BACKGROUND);
    this.camera = new PerspectiveCamera(35, 1, 0.001, 100);
    this.scene.add(this.camera);
    this.scene.add(new HemisphereLight(0xffffff, 0x60606a, 0.85));
    const key = new DirectionalLight(0xffffff, 1.6);
    key.position.set(0.35, 0.55, 0.2); // camera space: above, right of and a little behind the eye
    key.target.position.set(0, 0, -1);
    this.camera.add(key, key.target);

    this.setupFrame();
    this.camera.up.copy(this.axes.distal);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.enableDamping = false;
    this.controls.zoomToCursor = true;
    this.controls.addEventListener("change", () => this.requestRender());

    this.marker = new Mesh(new SphereGeometry(1, 20, 14), new MeshBasicMaterial({ color: MARKER_COLOUR }));
    this.marker.visible = false;
    this.marker.name = "ergohand-pick-marker";
    this.scene.add(this.marker);

    this.resize();
    new ResizeObserver(() => this.resize()).observe(this.host);
    this.setupPicking();
  }

  // The hand's frame for the view presets: from data.frame, else the model's axes.
  setupFrame() {
    const f = this.data.frame;
    const vec = (v, fallback) =>
      Array.isArray(v) && v.length === 3 && v.every(Number.isFinite) && Math.hypot(...v) > 0
        ? new Vector3(...v).normalize()
        : fallback;
    const fromData = f && typeof f === "object";
    const dorsal = vec(fromData && f.dorsal, new Vector3(0, 1, 0));
    const radial = vec(fromData && f.radial, new Vector3(1, 0, 0));
    let distal = vec(fromData && f.distal, null);
    if (!distal || Math.abs(distal.dot(dorsal)) > 0.99) distal = new Vector3().crossVectors(radial, dorsal).normalize();
    if (distal.lengthSq() < 0.5) distal = new Vector3(0, 0, 1);
    this.axes = { dorsal, radial, distal };
  }

  resize() {
    const w = Math.max(1, this.host.clientWidth), h = Math.max(1, this.host.clientHeight);
    this.renderer.setSize(w, h, false);
    this.renderer.domElement.style.width = "100%";
    this.renderer.domElement.style.height = "100%";
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  requestRender() {
    if (this.renderQueued) return;
    this.renderQueued = true;
    requestAnimationFrame(() => {
      this.renderQueued = false;
      this.renderNow();
    });
  }

  renderNow() {
    this.renderer.render(this.scene, this.camera);
  }

  // Pixels of the drawing buffer that differ from the background (read right after a render).
  countPixels() {
    this.renderNow();
    const gl = this.renderer.getContext();
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const px = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const [r, g, b] = BACKGROUND_RGB;
    let k = 0;
    for (let i = 0; i < px.length; i += 4) {
      if (Math.abs(px[i] - r) > 8 || Math.abs(px[i + 1] - g) > 8 || Math.abs(px[i + 2] - b) > 8) k++;
    }
    return { nonBackground: k, total: w * h };
  }

  async load() {
    const loader = new GLTFLoader();
    const globalParts = Array.isArray(this.data.part_nodes) ? this.data.part_nodes : [];
    for (const [i, entry] of this.data.meshes.entries()) {
      if (!entry || typeof entry.glb !== "string") throw new Error(`meshes[${i}] has no "glb" element id`);
      const script = byId(entry.glb);
      if (!script) throw new Error(`meshes[${i}]: no element with id "${entry.glb}" (its GLB) in the page`);
      let t = performance.now();
      const bytes = decodeBase64(script.textContent);
      this.timings.decode += performance.now() - t;
      t = performance.now();
      let gltf;
      try {
        gltf = await parseGlb(loader, bytes);
        this.timings.parse += performance.now() - t;
      } catch (e) {
        throw new Error(`${entry.glb} (${entry.name || "GLB"}): ${e && e.message ? e.message : e}`);
      }
      script.textContent = ""; // the base64 text is not needed any more
      this.addGltf(gltf, entry, new Set([...globalParts, ...(Array.isArray(entry.parts) ? entry.parts : [])]));
    }
    if (this.data.rig && typeof this.data.rig === "object") this.addRig(this.data.rig);
    this.scene.updateMatrixWorld(true);
    for (const m of this.meshes) {
      if (m.mesh.isSkinnedMesh) {
        // bounds of the skinned positions (three does not derive them from the bind pose);
        // no culling, so that an animation never needs them per frame
        m.mesh.computeBoundingBox();
        m.mesh.computeBoundingSphere();
        m.mesh.frustumCulled = false;
      }
    }
  }

  addGltf(gltf, entry, partNames) {
    const root = gltf.scene || (gltf.scenes && gltf.scenes[0]);
    if (!root) return;
    const wholePart = entry.role === "part";
    const valueSpec = entry.value && typeof entry.value === "object" && entry.value.attribute ? entry.value : null;
    root.traverse((o) => {
      if (!o.isMesh) return;
      const g = o.geometry;
      if (!g.getAttribute("normal")) {
        const t = performance.now();
        smoothNormals(g);
        this.timings.normals += performance.now() - t;
        // GLTFLoader gives a mesh without normals a flat-shaded copy of its material
        for (const m of Array.isArray(o.material) ? o.material : [o.material]) {
          if (m.flatShading) {
            m.flatShading = false;
            m.needsUpdate = true;
          }
        }
      }
      const part = wholePart || isPart(o, gltf, partNames);
      if (part) {
        // its own material, so that the see-through setting leaves anything sharing it alone
        o.material = Array.isArray(o.material) ? o.material.map((m) => m.clone()) : o.material.clone();
      }
      let value = null;
      if (valueSpec) {
        const attr = g.getAttribute(threeAttributeName(valueSpec.attribute)) || g.getAttribute(valueSpec.attribute);
        if (attr) value = { attr, label: valueSpec.label || valueSpec.attribute, unit: valueSpec.unit || "" };
      }
      const rec = { mesh: o, gltf, name: nodeName(o, gltf), part, value };
      o.userData.ergohand = rec;
      this.meshes.push(rec);
      if (part) this.parts.push(rec);
    });
    this.scene.add(root);
    if (gltf.animations && gltf.animations.length) {
      const mixer = new AnimationMixer(root);
      for (const clip of gltf.animations) {
        mixer.clipAction(clip).play();
        this.clipDuration = Math.max(this.clipDuration, clip.duration);
      }
      mixer.setTime(0);
      this.mixers.push(mixer);
    }
  }

  // A hand the page poses itself (data.rig): shown as written, re-skinned when a joint moves.
  addRig(rig) {
    const script = byId(rig.bin);
    if (!script) throw new Error(`rig: no element with id "${rig.bin}" (its arrays) in the page`);
    if (!Array.isArray(rig.joints) || !Array.isArray(rig.link_names) || !rig.root) throw new Error("rig: joints, link_names or root missing");
    const arrays = decodeRig(rig, decodeBase64(script.textContent));
    script.textContent = "";
    const n = arrays.n;
    const geometry = new BufferGeometry();
    geometry.setAttribute("position", new BufferAttribute(new Float32Array(3 * n), 3));
    geometry.setIndex(new BufferAttribute(arrays.faces, 1));
    const mesh = new Mesh(geometry, new MeshStandardMaterial({ color: SKIN_COLOUR, roughness: 0.75, metalness: 0 }));
    mesh.name = "hand";
    const rec = { mesh, gltf: null, name: "hand", part: false, value: null };
    mesh.userData.ergohand = rec;
    this.meshes.push(rec);
    this.scene.add(mesh);
    this.rig = {
      data: rig,
      arrays,
      written: rig.joints.map((j) => j.deg.map(Number)),
      deg: rig.joints.map((j) => j.deg.map(Number)),
      mm: new Float64Array(3 * n), // the live skin, mm
      live: false,
    };
    this.showWritten();
  }

  // Put `mm` (xyz per vertex, millimetres) on the rig's mesh.
  setRigPositions(mm) {
    const mesh = this.meshes.find((r) => r.mesh.name === "hand" && r.gltf === null).mesh;
    const pos = mesh.geometry.getAttribute("position");
    for (let i = 0; i < mm.length; i++) pos.array[i] = mm[i] / this.scale;
    pos.needsUpdate = true;
    mesh.geometry.computeVertexNormals();
    mesh.geometry.computeBoundingBox();
    mesh.geometry.computeBoundingSphere();
    if (this.picked && this.picked.rec === mesh.userData.ergohand) this.clearPick();
    this.requestRender();
  }

  // The geometry the command wrote, at its angles.
  showWritten() {
    const r = this.rig;
    r.deg = r.written.map((d) => d.slice());
    r.live = false;
    this.setRigPositions(r.arrays.shown);
    if (this.onRig) this.onRig();
  }

  // The rest skin skinned at the current angles by the ported forward kinematics and DQS.
  reskin() {
    const r = this.rig;
    dualQuaternionSkin(r.arrays, linkTransforms(r.data, r.deg), r.mm);
    r.live = true;
    this.setRigPositions(r.mm);
    if (this.onRig) this.onRig();
  }

  // Set one joint angle (degrees, clamped to its limits) and re-skin.
  setJointAngle(k, dof, deg) {
    const j = this.rig.data.joints[k];
    const [lo, hi] = j.limits_deg[dof];
    this.rig.deg[k][dof] = Math.min(hi, Math.max(lo, Number(deg) || 0));
    this.reskin();
  }

  // world box of every visible mesh
  visibleBox() {
    this.scene.updateMatrixWorld(true);
    const box = new Box3(), b = new Box3();
    for (const { mesh } of this.meshes) {
      if (!visibleInScene(mesh)) continue;
      if (mesh.isSkinnedMesh) {
        if (!mesh.boundingBox) mesh.computeBoundingBox();
        b.copy(mesh.boundingBox);
      } else {
        if (!mesh.geometry.boundingBox) mesh.geometry.computeBoundingBox();
        b.copy(mesh.geometry.boundingBox);
      }
      box.union(b.applyMatrix4(mesh.matrixWorld));
    }
    return box;
  }

  // Up to ~40k points of the visible meshes, in world space (every vertex of a small mesh, a
  // regular sample of a large one), for a framing that is tight from any direction.
  visiblePoints() {
    this.scene.updateMatrixWorld(true);
    const visible = this.meshes.filter((r) => visibleInScene(r.mesh));
    const total = visible.reduce((n, r) => n + r.mesh.geometry.getAttribute("position").count, 0);
    const step = Math.max(1, Math.ceil(total / 40000));
    const pts = [];
    const v = new Vector3();
    for (const { mesh } of visible) {
      const n = mesh.geometry.getAttribute("position").count;
      for (let i = 0; i < n; i += step) {
        mesh.getVertexPosition(i, v); // skinned meshes: the skinned position
        pts.push(v.clone().applyMatrix4(mesh.matrixWorld));
      }
    }
    return pts;
  }

  // Put the camera on the side `dir` points to, looking with the frame's distal direction up,
  // at the middle of what is visible and just far enough for all of it to fit in the view.
  fit(dir) {
    const box = this.visibleBox();
    if (box.isEmpty()) return;
    const center = box.getCenter(new Vector3());
    const r = Math.max(box.getBoundingSphere(new Sphere()).radius, 1e-6);
    this.radius = r;
    const d = (dir || new Vector3().subVectors(this.camera.position, this.controls.target)).clone();
    if (d.lengthSq() < 1e-20) d.copy(this.axes.dorsal);
    d.normalize();
    // keep off the up axis (OrbitControls cannot look straight along it)
    if (Math.abs(d.dot(this.axes.distal)) > 0.999) d.addScaledVector(this.axes.dorsal, 0.01).normalize();
    const right = new Vector3().crossVectors(this.axes.distal, d).normalize();
    const up = new Vector3().crossVectors(d, right);
    const tanV = Math.tan((this.camera.fov * Math.PI) / 360);
    const tanH = tanV * this.camera.aspect;
    const pts = this.visiblePoints();
    // centre the extent across the view, then back off until every point is inside
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    const rel = new Vector3();
    for (const p of pts) {
      rel.subVectors(p, center);
      const x = rel.dot(right), y = rel.dot(up);
      x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
    }
    const target = center.clone().addScaledVector(right, (x0 + x1) / 2).addScaledVector(up, (y0 + y1) / 2);
    let dist = 0;
    for (const p of pts) {
      rel.subVectors(p, target);
      const z = rel.dot(d); // toward the camera
      dist = Math.max(dist, z + Math.abs(rel.dot(right)) / tanH, z + Math.abs(rel.dot(up)) / tanV);
    }
    dist = Math.max(dist * 1.08, r * 0.1);
    this.camera.up.copy(this.axes.distal);
    // perspective makes the near side look bigger: re-centre on the projected extent and
    // scale the distance to it, a few times (it converges quickly)
    const ndc = new Vector3();
    for (let iter = 0; iter < 4; iter++) {
      this.camera.near = Math.max(dist - 4 * r, dist / 200);
      this.camera.far = dist + 20 * r;
      this.camera.updateProjectionMatrix();
      this.camera.position.copy(target).addScaledVector(d, dist);
      this.camera.lookAt(target);
      this.camera.updateMatrixWorld(true);
      let nx0 = Infinity, nx1 = -Infinity, ny0 = Infinity, ny1 = -Infinity;
      for (const p of pts) {
        ndc.copy(p).project(this.camera);
        nx0 = Math.min(nx0, ndc.x); nx1 = Math.max(nx1, ndc.x); ny0 = Math.min(ny0, ndc.y); ny1 = Math.max(ny1, ndc.y);
      }
      if (!Number.isFinite(nx0 + nx1 + ny0 + ny1)) break;
      target.addScaledVector(right, ((nx0 + nx1) / 2) * tanH * dist).addScaledVector(up, ((ny0 + ny1) / 2) * tanV * dist);
      const span = Math.max((nx1 - nx0) / 2, (ny1 - ny0) / 2);
      if (Math.abs(span - 0.92) < 0.01) break;
      dist *= 1 + (span / 0.92 - 1) * 0.9;
    }
    this.camera.near = Math.max(dist - 4 * r, dist / 200);
    this.camera.far = dist + 20 * r;
    this.camera.updateProjectionMatrix();
    this.camera.position.copy(target).addScaledVector(d, dist);
    this.controls.target.copy(target);
    this.camera.lookAt(target);
    this.controls.minDistance = r * 0.02;
    this.controls.maxDistance = dist * 20;
    this.controls.update();
    const s = 0.012 * r;
    this.marker.scale.set(s, s, s);
    this.requestRender();
  }

  presetDirection(name) {
    const { dorsal, radial, distal } = this.axes;
    switch (name) {
      case "dorsal": return dorsal.clone();
      case "palmar": return dorsal.clone().negate();
      case "radial": return radial.clone();
      case "ulnar": return radial.clone().negate();
      case "distal": return distal.clone().addScaledVector(dorsal, 0.05);
      default: // three-quarter view from the dorsal-radial side (a hand: a little from the
        // wrist; without a frame: a little from above)
        return dorsal.clone().multiplyScalar(0.8).addScaledVector(radial, 0.75).addScaledVector(distal, this.data.frame ? -0.35 : 0.45);
    }
  }

  view(name) {
    if (name === "fit") this.fit(null);
    else this.fit(this.presetDirection(name));
  }

  setPartOpacity(alpha) {
    const a = Math.min(1, Math.max(0, Number(alpha)));
    for (const { mesh } of this.parts) {
      for (const m of Array.isArray(mesh.material) ? mesh.material : [mesh.material]) {
        const transparent = a < 0.999;
        if (m.transparent !== transparent) m.needsUpdate = true;
        m.transparent = transparent;
        m.opacity = a;
        m.depthWrite = !transparent;
      }
    }
    this.requestRender();
  }

  setPartHidden(hidden) {
    for (const { mesh } of this.parts) mesh.visible = !hidden;
    if (hidden && this.picked && this.picked.rec.part) this.clearPick();
    this.requestRender();
  }

  setTime(t) {
    this.time = Math.min(this.clipDuration, Math.max(0, Number(t) || 0));
    for (const m of this.mixers) m.setTime(this.time);
    for (const { mesh } of this.meshes) {
      if (mesh.isSkinnedMesh) mesh.boundingBox = mesh.boundingSphere = null; // recomputed when needed
    }
    if (this.onTime) this.onTime(this.time);
    this.requestRender();
  }

  // ---- picking

  setupPicking() {
    const canvas = this.renderer.domElement;
    let down = null;
    canvas.addEventListener("pointerdown", (e) => {
      down = e.button === 0 ? { x: e.clientX, y: e.clientY } : null;
    });
    canvas.addEventListener("pointerup", (e) => {
      if (!down || e.button !== 0) return;
      const moved = Math.hypot(e.clientX - down.x, e.clientY - down.y);
      down = null;
      if (moved < 5) this.pickAt(e.clientX, e.clientY);
    });
    this.raycaster = new Raycaster();
  }

  pickAt(clientX, clientY) {
    const rect = this.renderer.domElement.getBoundingClientRect();
    const ndc = new Vector2(((clientX - rect.left) / rect.width) * 2 - 1, -((clientY - rect.top) / rect.height) * 2 + 1);
    this.raycaster.setFromCamera(ndc, this.camera);
    const targets = this.meshes.filter((r) => visibleInScene(r.mesh)).map((r) => r.mesh);
    const hits = this.raycaster.intersectObjects(targets, false);
    // a see-through part lets the click reach what is behind it when that is close
    const hit = hits.find((h) => !(h.object.userData.ergohand.part && h.object.material.opacity < 0.5)) || hits[0];
    if (!hit) {
      this.clearPick();
      return null;
    }
    const rec = hit.object.userData.ergohand;
    const p = hit.point;
    const out = { name: rec.name, point_mm: [p.x, p.y, p.z].map((c) => c * this.scale) };
    if (rec.value && hit.face && hit.barycoord) {
      const { attr } = rec.value, f = hit.face, w = hit.barycoord;
      out.value = attr.getX(f.a) * w.x + attr.getX(f.b) * w.y + attr.getX(f.c) * w.z;
      out.label = rec.value.label;
      out.unit = rec.value.unit;
    }
    this.picked = { rec, out };
    this.marker.position.copy(p);
    this.marker.visible = true;
    this.requestRender();
    if (this.onPick) this.onPick(out);
    return out;
  }

  clearPick() {
    this.picked = null;
    this.marker.visible = false;
    if (this.onPick) this.onPick(null);
    this.requestRender();
  }

  // ---- animation

  play(on) {
    this.playing = on && this.clipDuration > 0;
    if (!this.playing) return;
    let last = performance.now();
    const step = (now) => {
      if (!this.playing) return;
      let t = this.time + (now - last) / 1000;
      last = now;
      if (t > this.clipDuration) t = 0;
      this.setTime(t);
      requestAnimationFrame(step);
    };
    requestAnimationFrame(step);
  }
}

// ---------------------------------------------------------------------------------------------
// panels

function buildToolbar(viewer, data) {
  const bar = byId("eh-toolbar");
  if (!bar) return;
  const views = el("span", { class: "eh-group", title: "view presets" });
  for (const [name, label] of [["dorsal", "dorsal"], ["palmar", "palmar"], ["radial", "radial"], ["ulnar", "ulnar"], ["fit", "fit"]]) {
    views.append(el("button", { type: "button", "data-view": name, onclick: () => viewer.view(name) }, label));
  }
  bar.append(views);
  if (!data.frame) views.title = "view presets (no hand frame in the data: along the model's ±Y and ±X)";

  if (viewer.parts.length) {
    const hide = el("input", { type: "checkbox", id: "eh-hide-part" });
    hide.addEventListener("change", () => viewer.setPartHidden(hide.checked));
    const opacity = el("input", { type: "range", id: "eh-part-opacity", min: "0", max: "100", value: "100" });
    opacity.addEventListener("input", () => viewer.setPartOpacity(Number(opacity.value) / 100));
    bar.append(el("span", { class: "eh-group" },
      el("label", null, hide, " hide part"),
      el("label", { title: "opacity of the part" }, "see-through ", opacity)));
    viewer.controlsDom = { hide, opacity };
  }

  if (viewer.clipDuration > 0) {
    const slider = el("input", { type: "range", id: "eh-time", min: "0", max: String(viewer.clipDuration), step: "any", value: "0" });
    const label = el("span", { class: "eh-time-label" }, "0.00 s");
    const play = el("button", { type: "button" }, "play");
    slider.addEventListener("input", () => { viewer.play(false); play.textContent = "play"; viewer.setTime(Number(slider.value)); });
    play.addEventListener("click", () => {
      const on = !viewer.playing;
      viewer.play(on);
      play.textContent = on ? "pause" : "play";
    });
    viewer.onTime = (t) => { slider.value = String(t); label.textContent = t.toFixed(2) + " s"; };
    bar.append(el("span", { class: "eh-group" }, play, slider, label));
  }
}

const DOF_SHORT = { flexion: "flex", abduction: "abd", axial: "rot" };
const DIGITS = [["WRIST", "wrist"], ["T_", "thumb"], ["I_", "index"], ["M_", "middle"], ["R_", "ring"], ["L_", "little"]];

// One slider per joint angle, grouped by digit, and what the hand shows now.
function buildJoints(viewer) {
  const rig = viewer.rig;
  if (!rig) return;
  const box = el("section", { id: "eh-joints" });
  const facts = byId("eh-facts");
  if (facts) facts.before(box); else byId("eh-readout").after(box);
  const shown = el("div", { class: "eh-readout-body", id: "eh-rig-shown" });
  const written = el("button", { type: "button", id: "eh-rig-written" }, "as written");
  const rest = el("button", { type: "button", id: "eh-rig-rest" }, "reference posture");
  box.append(el("h2", null, "joints (degrees)"), el("div", { class: "eh-group" }, written, rest), shown);
  const inputs = [];
  for (const [prefix, label] of DIGITS) {
    const group = el("details", prefix === "I_" ? { open: "" } : null, el("summary", null, label));
    rig.data.joints.forEach((j, k) => {
      if (!j.name.startsWith(prefix)) return;
      j.dof_names.forEach((dofName, d) => {
        const [lo, hi] = j.limits_deg[d];
        const input = el("input", { type: "range", id: `eh-joint-${j.name}-${d}`, min: String(lo), max: String(hi), step: "0.5", value: String(rig.deg[k][d]) });
        const value = el("span", { class: "eh-time-label" });
        input.addEventListener("input", () => viewer.setJointAngle(k, d, Number(input.value)));
        inputs.push({ input, value, k, d });
        group.append(el("div", { class: "eh-entry", title: `${j.name} ${dofName}: ${lo} to ${hi}°` },
          el("span", { style: "min-width:7.5em" }, `${j.name} ${DOF_SHORT[dofName] || dofName}`), input, value));
      });
    });
    if (group.children.length > 1) box.append(group);
  }
  written.addEventListener("click", () => viewer.showWritten());
  rest.addEventListener("click", () => {
    rig.deg = rig.deg.map((d) => d.map(() => 0));
    viewer.reskin();
  });
  viewer.onRig = () => {
    for (const { input, value, k, d } of inputs) {
      input.value = String(rig.deg[k][d]);
      value.textContent = rig.deg[k][d].toFixed(1) + "°";
    }
    shown.textContent = "shown: " + (rig.live ? rig.data.live_label : rig.data.shown_label);
  };
  viewer.onRig();
}

function buildLegend(legend) {
  const box = byId("eh-legend");
  if (!box) return;
  if (!legend || typeof legend !== "object") {
    box.remove();
    return;
  }
  const unit = legend.unit ? " " + legend.unit : "";
  box.append(el("h2", null, legend.title || "legend"));
  const swatch = (colour, label) =>
    el("div", { class: "eh-entry" }, el("span", { class: "eh-swatch", style: `background:${String(colour)}` }), el("span", null, label ?? ""));
  if (Array.isArray(legend.entries)) {
    for (const e of legend.entries) if (e) box.append(swatch(e.colour, e.label));
  }
  const g = legend.gradient;
  if (g && typeof g === "object") {
    const stops = COLORMAPS[String(g.colormap || "viridis").toLowerCase()] || COLORMAPS.viridis;
    const css = stops.map((c, i) => `${c} ${((100 * i) / (stops.length - 1)).toFixed(1)}%`).join(", ");
    box.append(el("div", { class: "eh-gradient", style: `background:linear-gradient(to right, ${css})` }));
    const lo = Number(g.min), hi = Number(g.max);
    if (Number.isFinite(lo) && Number.isFinite(hi)) {
      box.append(el("div", { class: "eh-ticks" },
        el("span", null, fmt(lo) + unit), el("span", null, fmt((lo + hi) / 2) + unit), el("span", null, fmt(hi) + unit)));
    }
  }
  if (legend.beyond && typeof legend.beyond === "object") box.append(swatch(legend.beyond.colour, legend.beyond.label));
}

function buildFacts(data) {
  const box = byId("eh-facts");
  if (!box) return;
  const facts = Array.isArray(data.facts) ? data.facts.filter((f) => Array.isArray(f) && f.length >= 1) : [];
  const tables = Array.isArray(data.tables) ? data.tables.filter((t) => t && typeof t === "object") : [];
  if (!facts.length && !tables.length) {
    box.remove();
    return;
  }
  if (facts.length) {
    const t = el("table", { class: "eh-facts" });
    for (const [k, v] of facts) t.append(el("tr", null, el("th", null, k ?? ""), el("td", null, v ?? "")));
    box.append(t);
  }
  for (const tab of tables) {
    if (tab.title) box.append(el("h2", null, tab.title));
    const t = el("table", { class: "eh-table" });
    if (Array.isArray(tab.columns)) t.append(el("tr", null, ...tab.columns.map((c) => el("th", null, c ?? ""))));
    if (Array.isArray(tab.rows)) {
      for (const row of tab.rows) if (Array.isArray(row)) t.append(el("tr", null, ...row.map((c) => el("td", null, c ?? ""))));
    }
    box.append(t);
  }
}

function buildReadout(viewer) {
  const box = byId("eh-readout");
  if (!box) return;
  const body = el("div", { class: "eh-readout-body" }, "click on the model to read a point");
  box.append(el("h2", null, "picked point"), body);
  viewer.onPick = (out) => {
    body.replaceChildren();
    if (!out) {
      body.append("click on the model to read a point");
      return;
    }
    const p = out.point_mm.map((c) => c.toFixed(1)).join(", ");
    const rows = [["on", out.name], ["point (mm)", p]];
    if (out.value !== undefined) rows.push([out.label, (Number.isFinite(out.value) ? out.value.toFixed(2) : String(out.value)) + (out.unit ? " " + out.unit : "")]);
    const t = el("table", { class: "eh-facts" });
    for (const [k, v] of rows) t.append(el("tr", null, el("th", null, k), el("td", null, v)));
    body.append(t);
  };
}

// ---------------------------------------------------------------------------------------------

function fail(err, viewer) {
  const msg = err && err.message ? err.message : String(err);
  console.error("ergohand view: " + msg);
  const s = byId("eh-status");
  if (s) {
    s.textContent = "cannot show this view: " + msg;
    s.className = "eh-error";
  }
  window.ergohandView = { ready: false, error: msg, meshes: viewer ? viewer.meshes.length : 0 };
}

async function main() {
  let viewer = null;
  try {
    const data = readData();
    const kind = byId("eh-kind");
    if (kind && data.kind) kind.textContent = String(data.kind);
    buildLegend(data.legend);
    buildFacts(data);
    viewer = new Viewer(data);
    buildReadout(viewer);
    await viewer.load();
    buildToolbar(viewer, data);
    buildJoints(viewer);
    let t = performance.now();
    // The output may name its first view (a grasp: the palm, where the contacts are) and how
    // much of the part shows at first.
    const first = ["dorsal", "palmar", "radial", "ulnar"].includes(data.view) ? data.view : "initial";
    viewer.fit(viewer.presetDirection(first));
    if (typeof data.part_opacity === "number" && viewer.parts.length && viewer.controlsDom) {
      const a = Math.min(1, Math.max(0, data.part_opacity));
      viewer.setPartOpacity(a);
      viewer.controlsDom.opacity.value = String(Math.round(100 * a));
    }
    viewer.timings.fit = performance.now() - t;
    t = performance.now();
    const status = byId("eh-status");
    if (viewer.meshes.length === 0) {
      status.textContent = "nothing to show: the page holds no mesh";
    } else {
      status.remove();
    }
    const { nonBackground, total } = viewer.countPixels(); // renders the first frame
    viewer.timings.firstFrame = performance.now() - t;
    for (const k of Object.keys(viewer.timings)) viewer.timings[k] = Math.round(viewer.timings[k]);
    // performance.now() counts from the navigation's start; T0 is when this script began
    const loadMs = Math.round(performance.now());
    const scriptMs = Math.round(performance.now() - T0);
    let triangles = 0;
    for (const { mesh } of viewer.meshes) triangles += triangleCount(mesh.geometry);
    window.ergohandView = {
      version: 1,
      ready: true,
      meshes: viewer.meshes.length,
      parts: viewer.parts.length,
      triangles,
      nonBackgroundPixels: nonBackground,
      canvasPixels: total,
      loadMs,
      scriptMs,
      timings: viewer.timings,
      countPixels: () => viewer.countPixels(),
      // setSlider("part-opacity", 0..1) | setSlider("time", seconds); true when the slider exists
      setSlider(name, value) {
        if (name === "part-opacity" && viewer.parts.length) {
          viewer.setPartOpacity(value);
          if (viewer.controlsDom) viewer.controlsDom.opacity.value = String(Math.round(100 * value));
          return true;
        }
        if (name === "time" && viewer.clipDuration > 0) {
          viewer.setTime(value);
          return true;
        }
        return false;
      },
      // the rig: its joints ({name, dof_names, limits_deg}), setJoint(name, [deg...]) (true
      // when the page has that joint), the shown skin in mm, re-skin at the current angles,
      // back to the written geometry
      joints: viewer.rig ? viewer.rig.data.joints.map((j) => ({ name: j.name, dof_names: j.dof_names, limits_deg: j.limits_deg })) : [],
      setJoint(name, deg) {
        const k = viewer.rig ? viewer.rig.data.joints.findIndex((j) => j.name === name) : -1;
        if (k < 0) return false;
        const j = viewer.rig.data.joints[k];
        deg.forEach((v, d) => {
          if (d < j.limits_deg.length) viewer.rig.deg[k][d] = Math.min(j.limits_deg[d][1], Math.max(j.limits_deg[d][0], Number(v) || 0));
        });
        viewer.reskin();
        return true;
      },
      rigAngles: () => (viewer.rig ? viewer.rig.deg.map((d) => d.slice()) : null),
      rigPositionsMm: () => (viewer.rig ? Array.from(viewer.rig.live ? viewer.rig.mm : viewer.rig.arrays.shown) : null),
      reskin: () => { if (viewer.rig) viewer.reskin(); return !!viewer.rig; },
      showWritten: () => { if (viewer.rig) viewer.showWritten(); return !!viewer.rig; },
      setPartHidden: (h) => { viewer.setPartHidden(!!h); if (viewer.controlsDom) viewer.controlsDom.hide.checked = !!h; },
      view: (name) => viewer.view(name),
      pick: (x, y) => viewer.pickAt(x, y),
    };
    document.documentElement.setAttribute("data-ergohand-ready", "1");
  } catch (err) {
    fail(err, viewer);
  }
}

main();
