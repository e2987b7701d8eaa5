// Decode every EXT_meshopt_compression bufferView of a .glb with meshoptimizer's own decoder.
// Usage: node decode_meshopt.mjs FILE.glb OUT_DIR  -> OUT_DIR/bufferView_<i>.bin, the decoded bytes.
import { readFile, writeFile } from "node:fs/promises";
import { MeshoptDecoder } from "meshoptimizer";

const [path, outDir] = process.argv.slice(2);
const glb = await readFile(path);
if (glb.readUInt32LE(0) !== 0x46546c67) throw new Error("not a GLB");
const jsonLength = glb.readUInt32LE(12);
const gltf = JSON.parse(glb.subarray(20, 20 + jsonLength).toString("utf8"));
const binStart = 20 + jsonLength + 8; // the BIN chunk is buffer 0
await MeshoptDecoder.ready;
const decoded = [];
for (const [index, view] of gltf.bufferViews.entries()) {
  const ext = view.extensions?.EXT_meshopt_compression;
  if (!ext) continue;
  if (ext.buffer !== 0) throw new Error(`bufferView ${index}: compressed data outside the BIN chunk`);
  const source = glb.subarray(binStart + (ext.byteOffset ?? 0), binStart + (ext.byteOffset ?? 0) + ext.byteLength);
  const target = new Uint8Array(ext.count * ext.byteStride);
  MeshoptDecoder.decodeGltfBuffer(target, ext.count, ext.byteStride, source, ext.mode, ext.filter ?? "NONE");
  await writeFile(`${outDir}/bufferView_${index}.bin`, target);
  decoded.push(index);
}
process.stdout.write(JSON.stringify({ decoded }));
