// Validates GLB files with the Khronos glTF validator (npm `gltf-validator`).
//
// Usage: node tests/gltf/validate.mjs FILE.glb [FILE.glb ...]
// Prints one summary line per file (and every error or warning) and exits
// non-zero if any file has an error. Degenerate triangles, which the
// validator rates as information by default, are promoted to errors: a mesh
// silva writes must not contain them.
import { readFile } from 'node:fs/promises';
import { basename } from 'node:path';
import validator from 'gltf-validator';

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node validate.mjs FILE.glb [FILE.glb ...]');
  process.exit(2);
}

let failed = 0;
for (const file of files) {
  try {
    const bytes = new Uint8Array(await readFile(file));
    const report = await validator.validateBytes(bytes, {
      uri: basename(file),
      maxIssues: 100,
      severityOverrides: { ACCESSOR_INDEX_TRIANGLE_DEGENERATE: 0 },
    });
    const { numErrors, numWarnings, numInfos, messages } = report.issues;
    console.log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
    for (const m of messages.filter((m) => m.severity <= 1)) {
      const level = m.severity === 0 ? 'error' : 'warning';
      console.log(`  ${level} ${m.code} at ${m.pointer ?? '-'}: ${m.message}`);
    }
    if (numErrors > 0) failed += 1;
  } catch (err) {
    console.log(`${file}: validator could not read the file: ${err}`);
    failed += 1;
  }
}
process.exit(failed === 0 ? 0 : 1);
