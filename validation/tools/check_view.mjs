// Open ergohand view pages (view.html) in headless Chromium and fail on what a reader would see
// go wrong. Run by check_view.sh, which installs Chromium and playwright-core first:
//
//   node validation/tools/check_view.mjs [--screenshot DIR] PAGE.html [MORE.html ...]
//
// Each page is copied alone into an empty temporary folder and opened from there (file://) with
// the network off (Playwright's offline mode, and every host name resolving to nothing), so a
// page that needs anything beside itself fails. A page fails on:
//   - any console message of type "error" (this includes resources that failed to load and
//     WebGL errors Chromium reports to the console) or any uncaught exception;
//   - any request other than the page itself and data:/blob: URLs;
//   - the page not setting window.ergohandView.ready within 30 s of navigation (or setting
//     window.ergohandView.error);
//   - a blank canvas: fewer than 0.5 % (and at least 2000) of the canvas' pixels differing from
//     its background, counted here from the canvas itself (drawn into a 2-D canvas), not
//     taken from the page's own report; or no mesh at all;
//   - a page with joint sliders (a posed hand) where moving one slider, through the page's own
//     range input, changes fewer than 0.2 % (and 1000) of the canvas' pixels;
//   - a page whose data names a per-vertex value to read out (meshes[].value) where no click
//     on a grid over the canvas reads a finite value out.
// With --agree-obj, a page X.view.html with joint sliders is also compared with X.obj beside
// it: the page re-skins the hand at the page's angles with its port of the toolkit's forward
// kinematics and dual-quaternion skinning, and fails unless every vertex is within 0.01 mm of
// the OBJ's (which must have been written by `ergohand pose --keep-angles --plain-skinning`:
// check_pose_pages.sh makes such pairs).
//
// Environment: CHROMIUM (the browser binary, default /usr/bin/chromium); VIEW_CHECK_DIR (where
// `npm install playwright-core` was run, default: the current folder).
// Exit status: 0 every page passes; 1 a page failed; 2 set-up error.
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { createRequire } from "node:module";
import { pathToFileURL } from "node:url";

const READY_TIMEOUT_MS = 30000;
const SETTLE_MS = 500; // after ready, for late errors (e.g. in the first animation frames)
const MIN_FRACTION = 0.005;
const MIN_PIXELS = 2000;
const SLIDER_MIN_FRACTION = 0.002;
const SLIDER_MIN_PIXELS = 1000;
const AGREE_MM = 0.01;

// WebGL in headless Chromium on a machine without a GPU: ANGLE on SwiftShader (Chromium's
// bundled CPU Vulkan), asked for explicitly; without --enable-unsafe-swiftshader, Chromium
// 13x+ deprecates (and will drop) the automatic fallback to software WebGL.
const WEBGL_FLAGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"];
const QUIET_FLAGS = [
  "--no-sandbox", "--disable-background-networking", "--disable-component-update", "--disable-sync",
  "--no-first-run", "--host-resolver-rules=MAP * ~NOTFOUND",
];

let args = process.argv.slice(2);
let shotDir = null;
let agreeObj = false;
for (;;) {
  if (args[0] === "--screenshot") {
    shotDir = args[1];
    args = args.slice(2);
    fs.mkdirSync(shotDir, { recursive: true });
  } else if (args[0] === "--agree-obj") {
    agreeObj = true;
    args = args.slice(1);
  } else break;
}
if (args.length === 0) {
  console.error("usage: check_view.mjs [--screenshot DIR] [--agree-obj] PAGE.html [MORE.html ...]");
  process.exit(2);
}

const dir = process.env.VIEW_CHECK_DIR || process.cwd();
let chromium;
try {
  ({ chromium } = createRequire(path.join(path.resolve(dir), "noop.js"))("playwright-core"));
} catch (e) {
  console.error(`check_view: cannot load playwright-core from ${dir}: run 'npm install playwright-core' there or set VIEW_CHECK_DIR`);
  process.exit(2);
}

const executablePath = process.env.CHROMIUM || "/usr/bin/chromium";
let browser;
try {
  browser = await chromium.launch({ executablePath, headless: true, args: [...QUIET_FLAGS, ...WEBGL_FLAGS] });
} catch (e) {
  console.error(`check_view: cannot start ${executablePath}: ${e.message.split("\n")[0]}`);
  process.exit(2);
}

// In the page: count the canvas' pixels that differ from its background (the colour most of its
// four corners have). preserveDrawingBuffer lets the WebGL canvas be drawn into a 2-D one; if
// that yields nothing, the page's own readPixels count is the fallback.
function countCanvas() {
  const c = document.querySelector("canvas");
  if (!c) return { error: "no canvas" };
  const w = c.width, h = c.height;
  const c2 = document.createElement("canvas");
  c2.width = w; c2.height = h;
  const ctx = c2.getContext("2d", { willReadFrequently: true });
  ctx.drawImage(c, 0, 0);
  const px = ctx.getImageData(0, 0, w, h).data;
  const at = (x, y) => { const i = 4 * (y * w + x); return [px[i], px[i + 1], px[i + 2], px[i + 3]]; };
  const corners = [at(0, 0), at(w - 1, 0), at(0, h - 1), at(w - 1, h - 1)];
  const key = (p) => p.join(",");
  const counts = {};
  for (const p of corners) counts[key(p)] = (counts[key(p)] || 0) + 1;
  const bg = corners.reduce((a, p) => (counts[key(p)] > counts[key(a)] ? p : a), corners[0]);
  let k = 0;
  for (let i = 0; i < px.length; i += 4) {
    if (Math.abs(px[i] - bg[0]) > 8 || Math.abs(px[i + 1] - bg[1]) > 8 || Math.abs(px[i + 2] - bg[2]) > 8 || px[i + 3] === 0) k++;
  }
  return { width: w, height: h, background: bg, nonBackground: k };
}

// In the page: the canvas' pixels as RGBA bytes, kept on window for pixelsChanged.
function keepCanvas() {
  const c = document.querySelector("canvas");
  const c2 = document.createElement("canvas");
  c2.width = c.width; c2.height = c.height;
  const ctx = c2.getContext("2d", { willReadFrequently: true });
  ctx.drawImage(c, 0, 0);
  window.__checkViewPixels = ctx.getImageData(0, 0, c.width, c.height).data;
}

// In the page: how many pixels differ (by more than 8 in a channel) from those keepCanvas kept.
function pixelsChanged() {
  const before = window.__checkViewPixels;
  const c = document.querySelector("canvas");
  const c2 = document.createElement("canvas");
  c2.width = c.width; c2.height = c.height;
  const ctx = c2.getContext("2d", { willReadFrequently: true });
  ctx.drawImage(c, 0, 0);
  const now = ctx.getImageData(0, 0, c.width, c.height).data;
  if (!before || before.length !== now.length) return { error: "the canvas changed size" };
  let k = 0;
  for (let i = 0; i < now.length; i += 4) {
    if (Math.abs(now[i] - before[i]) > 8 || Math.abs(now[i + 1] - before[i + 1]) > 8 || Math.abs(now[i + 2] - before[i + 2]) > 8) k++;
  }
  return { changed: k, total: c.width * c.height };
}

// In the page: move one joint slider through its range input (the index MCP's flexion, else
// the first) to the end of its range farther from where it is, as a user's drag does.
function moveASlider() {
  const input = document.getElementById("eh-joint-I_MCP-0") || document.querySelector("#eh-joints input[type=range]");
  if (!input) return { error: "no joint slider in the page" };
  const lo = Number(input.min), hi = Number(input.max), v = Number(input.value);
  const to = v - lo > hi - v ? lo : hi;
  input.value = String(to);
  input.dispatchEvent(new Event("input", { bubbles: true }));
  return { id: input.id, from: v, to };
}

const nextFrames = () => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));

// The vertices of an OBJ file, as written (mm).
function objVertices(file) {
  const out = [];
  for (const line of fs.readFileSync(file, "utf8").split("\n")) {
    if (line.startsWith("v ")) {
      const [, x, y, z] = line.trim().split(/\s+/);
      out.push(Number(x), Number(y), Number(z));
    }
  }
  return out;
}

// A page with joint sliders: a moved slider must change the picture; with --agree-obj, the
// page's own skinning must reproduce the OBJ beside it.
async function checkRig(page, file, problems, result) {
  await page.evaluate(keepCanvas);
  const moved = await page.evaluate(moveASlider);
  if (moved.error) {
    problems.push(moved.error);
    return;
  }
  await page.evaluate(nextFrames);
  const diff = await page.evaluate(pixelsChanged);
  if (diff.error) problems.push(diff.error);
  else {
    const need = Math.max(SLIDER_MIN_PIXELS, Math.ceil(SLIDER_MIN_FRACTION * diff.total));
    result.sliderPixels = diff.changed;
    result.slider = moved;
    if (diff.changed < need) problems.push(`moving ${moved.id} from ${moved.from} to ${moved.to} changed ${diff.changed} pixels (need ${need})`);
  }
  await page.evaluate(() => window.ergohandView.showWritten());
  if (!agreeObj) return;
  const obj = file.replace(/\.view\.html?$/i, ".obj");
  if (obj === file || !fs.existsSync(obj)) {
    problems.push(`--agree-obj: no ${path.basename(obj)} beside the page`);
    return;
  }
  const want = objVertices(obj);
  const got = await page.evaluate(() => { window.ergohandView.reskin(); return window.ergohandView.rigPositionsMm(); });
  if (!got || got.length !== want.length) {
    problems.push(`--agree-obj: the page's hand has ${got ? got.length / 3 : 0} vertices, ${path.basename(obj)} ${want.length / 3}`);
    return;
  }
  let worst = 0, at = 0;
  for (let i = 0; i < want.length; i += 3) {
    const d = Math.hypot(got[i] - want[i], got[i + 1] - want[i + 1], got[i + 2] - want[i + 2]);
    if (d > worst) { worst = d; at = i / 3; }
  }
  result.agreeMm = worst;
  if (!(worst <= AGREE_MM)) problems.push(`--agree-obj: vertex ${at} is ${worst.toFixed(4)} mm from ${path.basename(obj)} (limit ${AGREE_MM} mm)`);
}

// In the page: click (through the page's own pick) on a grid over the canvas until a hit
// reads a value out; the first such readout, or how many clicks hit anything.
function pickAValue() {
  const c = document.querySelector("canvas").getBoundingClientRect();
  let hits = 0;
  for (let i = 1; i < 24; i++) {
    for (let j = 1; j < 24; j++) {
      const out = window.ergohandView.pick(c.left + (c.width * i) / 24, c.top + (c.height * j) / 24);
      if (!out) continue;
      hits++;
      if (typeof out.value === "number" && Number.isFinite(out.value)) return { hits, out };
    }
  }
  return { hits };
}

async function check(file) {
  const problems = [];
  const work = fs.mkdtempSync(path.join(os.tmpdir(), "check-view-"));
  const copy = path.join(work, "view.html");
  fs.copyFileSync(file, copy);
  const url = pathToFileURL(copy).href;
  const context = await browser.newContext({ offline: true, viewport: { width: 1280, height: 800 } });
  const page = await context.newPage();
  page.on("console", (m) => {
    if (m.type() === "error") problems.push(`console error: ${m.text()}`);
  });
  page.on("pageerror", (e) => problems.push(`uncaught exception: ${e.message}`));
  page.on("crash", () => problems.push("the page crashed"));
  page.on("request", (r) => {
    const u = r.url();
    if (u !== url && !u.startsWith("data:") && !u.startsWith("blob:")) problems.push(`requested ${u.slice(0, 100)}`);
  });
  let result = null;
  const t0 = Date.now();
  try {
    await page.goto(url, { waitUntil: "load", timeout: READY_TIMEOUT_MS });
    await page.waitForFunction(() => window.ergohandView && (window.ergohandView.ready || window.ergohandView.error),
      null, { timeout: Math.max(1000, READY_TIMEOUT_MS - (Date.now() - t0)), polling: 50 });
    const wallMs = Date.now() - t0;
    await page.waitForTimeout(SETTLE_MS);
    const hook = await page.evaluate(() => {
      const v = window.ergohandView;
      return { ready: !!v.ready, error: v.error || null, meshes: v.meshes, triangles: v.triangles, loadMs: v.loadMs, nonBackgroundPixels: v.nonBackgroundPixels, joints: (v.joints || []).length,
        values: Array.from(JSON.parse(document.getElementById("ergohand-view-data").textContent).meshes || []).filter((m) => m && m.value).length };
    });
    result = { hook, wallMs };
    if (hook.error) problems.push(`the page reports: ${hook.error}`);
    else {
      const px = await page.evaluate(countCanvas);
      result.px = px;
      if (px.error) problems.push(px.error);
      else {
        let k = px.nonBackground;
        if (k === 0 && hook.nonBackgroundPixels > 0) k = hook.nonBackgroundPixels; // 2-D copy came out empty
        const need = Math.max(MIN_PIXELS, Math.ceil(MIN_FRACTION * px.width * px.height));
        result.nonBackground = k;
        if (!(hook.meshes > 0)) problems.push("no mesh in the scene");
        if (k < need) problems.push(`blank canvas: ${k} non-background pixels of ${px.width}x${px.height} (need ${need})`);
      }
      if (shotDir) await page.screenshot({ path: path.join(shotDir, path.basename(file).replace(/\.html?$/i, "") + ".png") });
      if (hook.joints > 0) await checkRig(page, file, problems, result);
      if (hook.values > 0) {
        const picked = await page.evaluate(pickAValue);
        if (!picked.out) problems.push(`no click reads a value out (${picked.hits} clicks hit a mesh)`);
        else result.picked = picked.out;
      }
    }
  } catch (e) {
    const msg = e.message.split("\n")[0];
    problems.push(/Timeout/i.test(msg) ? `not ready within ${READY_TIMEOUT_MS / 1000} s (${msg})` : msg);
  } finally {
    await context.close().catch(() => {});
    fs.rmSync(work, { recursive: true, force: true });
  }
  return { problems, result };
}

let failed = false;
for (const file of args) {
  if (!fs.existsSync(file)) {
    console.error(`check_view: ${file}: no such file`);
    failed = true;
    continue;
  }
  const { problems, result } = await check(file);
  if (problems.length) {
    failed = true;
    console.error(`check_view: ${file}: FAILED`);
    for (const p of [...new Set(problems)]) console.error(`  ${p}`);
  } else {
    const h = result.hook;
    console.log(`check_view: ${file}: ok: ${h.meshes} meshes, ${h.triangles} triangles, ${result.nonBackground} of ` +
      `${result.px.width * result.px.height} pixels drawn, ready ${h.loadMs} ms after navigation (${result.wallMs} ms wall)` +
      (h.joints > 0 ? `; ${h.joints} joints, a slider changed ${result.sliderPixels} pixels` : "") +
      (result.agreeMm !== undefined ? `; the page's skinning within ${result.agreeMm.toExponential(2)} mm of the OBJ` : "") +
      (result.picked ? `; a click reads ${result.picked.label} ${result.picked.value.toFixed(2)} ${result.picked.unit}` : ""));
  }
}
await browser.close();
process.exit(failed ? 1 : 0);
