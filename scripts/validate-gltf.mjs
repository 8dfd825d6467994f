#!/usr/bin/env node
// Validates a glTF 2.0 file (.glb or .gltf) with Khronos' validator installed by scripts/setup.sh
// (.local/node/node_modules/gltf-validator). Prints the validation report as JSON and exits with 1
// when it has errors, 2 when the file or the validator cannot be used, 0 otherwise.
//
//   node scripts/validate-gltf.mjs out/crab.glb
import { readFile } from 'node:fs/promises';
import { createRequire } from 'node:module';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const file = process.argv[2];
if (!file || process.argv.length > 3) {
  console.error('usage: node scripts/validate-gltf.mjs FILE.glb|FILE.gltf');
  process.exit(2);
}

let validator;
try {
  validator = createRequire(path.join(root, '.local/node/package.json'))('gltf-validator');
} catch (e) {
  console.error(`${path.join(root, '.local/node')}: gltf-validator is not installed (run scripts/setup.sh): ${e.message}`);
  process.exit(2);
}

let bytes;
try {
  bytes = new Uint8Array(await readFile(file));
} catch (e) {
  console.error(`${file}: cannot read the file: ${e.message}`);
  process.exit(2);
}

const dir = path.dirname(file);
try {
  const report = await validator.validateBytes(bytes, {
    uri: file,
    maxIssues: 0, // report every issue
    writeTimestamp: false,
    // External buffers and images of a .gltf are read from beside it.
    externalResourceFunction: (uri) =>
      readFile(path.resolve(dir, decodeURIComponent(uri))).then((b) => new Uint8Array(b)),
  });
  console.log(JSON.stringify(report, null, 2));
  // Not process.exit(): it would cut off a long report still being written to a pipe.
  process.exitCode = report.issues.numErrors > 0 ? 1 : 0;
} catch (e) {
  console.error(`${file}: the validator failed: ${e?.message ?? e}`);
  process.exit(2);
}
