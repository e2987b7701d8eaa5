// Validate one .glb/.gltf with the Khronos glTF validator; print its JSON report on stdout.
// Usage: node validate.mjs FILE
import { readFile } from "node:fs/promises";
import validator from "gltf-validator";

const path = process.argv[2];
const asset = await readFile(path);
const report = await validator.validateBytes(new Uint8Array(asset), {
  uri: path,
  maxIssues: 1000,
  // Every file facecap writes is self-contained: an external reference is itself a problem.
  externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri}`)),
});
process.stdout.write(JSON.stringify(report));
