// Writes the JSON schemas chronomap's Foxglove export embeds (src/export/foxglove.NAME.json)
// from Foxglove's published package, @foxglove/schemas (the version in package-lock.json):
//
//   npm ci && node write_schemas.mjs ../../../src/export
//
// read_mcap.mjs checks that the schemas in an exported file are these, field for field.
import fs from "node:fs";
import path from "node:path";
import * as schemas from "@foxglove/schemas/jsonschema.js";

export const NAMES = ["FrameTransform", "PointCloud", "SceneUpdate", "Grid"];

if (process.argv[1] && path.resolve(process.argv[1]) === path.resolve(new URL(import.meta.url).pathname)) {
  const out = process.argv[2];
  if (!out) {
    console.error("usage: node write_schemas.mjs OUT_FOLDER");
    process.exit(2);
  }
  for (const name of NAMES) {
    fs.writeFileSync(path.join(out, `foxglove.${name}.json`), JSON.stringify(schemas[name], null, 2) + "\n");
  }
}
