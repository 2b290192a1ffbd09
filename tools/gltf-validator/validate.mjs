// Khronos glTF Validator on one .glb or .gltf file: prints the JSON report on stdout.
//   node validate.mjs FILE
// External resources (a .gltf's .bin, images) are read relative to FILE.
// Exit status: 0 when the report was printed (whatever it says), 2 on bad usage or I/O errors.
import fs from 'node:fs/promises';
import path from 'node:path';
import * as validator from 'gltf-validator';

const file = process.argv[2];
if (!file || process.argv.length > 3) {
  console.error('usage: node validate.mjs FILE.glb|FILE.gltf');
  process.exit(2);
}

try {
  const bytes = new Uint8Array(await fs.readFile(file));
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 0, // unlimited
    externalResourceFunction: async (uri) =>
      new Uint8Array(await fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)))),
  });
  process.stdout.write(JSON.stringify(report, null, 2) + '\n');
} catch (error) {
  console.error(`validate.mjs: ${file}: ${error && error.message ? error.message : error}`);
  process.exit(2);
}
