// Validate glTF/GLB files with the Khronos glTF-Validator (npm package `gltf-validator`).
//
// Usage:  node validation/tools/gltf_validate.mjs FILE.glb [FILE2.gltf ...]
// The validator is looked up from the folder in GLTF_VALIDATOR_DIR (where
// `npm install gltf-validator` was run), else from the current folder.
// Prints one summary line per file plus every error and warning, and exits 1 when any file has
// errors (warnings, infos and hints do not fail), 2 when the validator cannot be loaded.
import fs from "node:fs";
import path from "node:path";
import { createRequire } from "node:module";

const dir = process.env.GLTF_VALIDATOR_DIR || process.cwd();
let validator;
try {
  validator = createRequire(path.join(path.resolve(dir), "noop.js"))("gltf-validator");
} catch (e) {
  console.error(`cannot load gltf-validator from ${dir}: run 'npm install gltf-validator' there or set GLTF_VALIDATOR_DIR`);
  process.exit(2);
}

let failed = false;
for (const file of process.argv.slice(2)) {
  const bytes = new Uint8Array(fs.readFileSync(file));
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 0,
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (err, data) =>
          err ? reject(err.toString()) : resolve(new Uint8Array(data)));
      }),
  });
  const i = report.issues;
  console.log(`${file}: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos, ${i.numHints} hints`);
  for (const m of i.messages) {
    if (m.severity <= 1) {
      const sev = m.severity === 0 ? "error" : "warning";
      console.log(`  ${sev} ${m.code} at ${m.pointer ?? m.offset ?? ""}: ${m.message}`);
    }
  }
  if (i.numErrors > 0) failed = true;
}
process.exit(failed ? 1 : 0);
