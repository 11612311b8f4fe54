// Reads chronomap's Foxglove export back with the readers Foxglove itself uses (@mcap/core, zstd
// chunks through @bokuweb/zstd-wasm) and checks it against Foxglove's published JSON schemas
// (@foxglove/schemas) and against what the command line answers for the same map:
//
//   node read_mcap.mjs CLI MAP.cmap MAP.mcap
//
// The channels, their schema names and encodings, each schema field for field, the statistics'
// and the messages' counts per channel, every log time against the sessions' times (`chronomap
// stats`), every message against its schema, and per channel one decoded message against the
// map: the last session's points against `chronomap snapshot` (.ply), the changed objects of
// each pair against `chronomap diff`, the cost grid's size and values, the map frame's transform.
// Prints "N passed, 0 failed" and exits 0, or names the first check that failed and exits 1.
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import fs from "node:fs";
import os from "node:os";
import path from "node:path";

import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import * as schemas from "@foxglove/schemas/jsonschema.js";
import { init as zstdInit, decompress as zstdDecompress } from "@bokuweb/zstd-wasm";

const [cli, mapPath, mcapPath] = process.argv.slice(2);
if (!mcapPath) {
  console.error("usage: node read_mcap.mjs CLI MAP.cmap MAP.mcap");
  process.exit(2);
}
let passed = 0;
function check(name, fn) {
  try {
    fn();
    passed++;
  } catch (e) {
    console.error(`FAILED: ${name}\n${e.stack ?? e}`);
    console.log(`${passed} passed, 1 failed`);
    process.exit(1);
  }
}
const run = (...args) => execFileSync(cli, args, { encoding: "utf8" });

// A JSON-schema check of the keywords Foxglove's schemas use: type, properties, required, items,
// oneOf of consts (enums), minimum and maximum.
function validate(schema, value, where) {
  const types = { object: (v) => v !== null && typeof v === "object" && !Array.isArray(v), array: Array.isArray,
    string: (v) => typeof v === "string", number: (v) => typeof v === "number", boolean: (v) => typeof v === "boolean",
    integer: Number.isInteger };
  if (schema.type) assert.ok(types[schema.type](value), `${where}: not a ${schema.type}: ${JSON.stringify(value)}`);
  if (schema.oneOf) assert.ok(schema.oneOf.some((o) => o.const === value), `${where}: ${value} is none of its enum`);
  if (schema.minimum !== undefined) assert.ok(value >= schema.minimum, `${where}: ${value} < ${schema.minimum}`);
  if (schema.maximum !== undefined) assert.ok(value <= schema.maximum, `${where}: ${value} > ${schema.maximum}`);
  for (const key of schema.required ?? []) assert.ok(key in value, `${where}: no field '${key}'`);
  if (schema.type === "object") {
    for (const [key, v] of Object.entries(value)) {
      assert.ok(schema.properties?.[key], `${where}: field '${key}' is not in the schema`);
      validate(schema.properties[key], v, `${where}.${key}`);
    }
  }
  if (schema.type === "array") value.forEach((v, i) => validate(schema.items, v, `${where}[${i}]`));
}

const TOPICS = {
  "/tf": "FrameTransform",
  "/map/occupied": "PointCloud",
  "/map/changes": "SceneUpdate",
  "/map/costmap": "Grid",
};

await zstdInit();
const bytes = fs.readFileSync(mcapPath);
const readable = {
  size: async () => BigInt(bytes.length),
  read: async (offset, size) => bytes.subarray(Number(offset), Number(offset + size)),
};
const decompressHandlers = { zstd: (buffer) => zstdDecompress(buffer) };
const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
const stats = JSON.parse(run("stats", mapPath, "--json"));
const sessions = stats.per_session;
const sessionNs = sessions.map((s) => BigInt(Math.floor(s.time_s)) * 1000000000n + BigInt(Math.round((s.time_s % 1) * 1e9)));

check("every record reads in order, chunk CRCs checked", () => {
  const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  stream.append(bytes);
  const kinds = new Set();
  for (let r; (r = stream.nextRecord()); ) kinds.add(r.type);
  assert.ok(stream.done(), "the stream reader did not reach the end magic");
  for (const k of ["Header", "Schema", "Channel", "Message", "MessageIndex", "ChunkIndex", "Statistics", "DataEnd", "Footer"]) {
    assert.ok(kinds.has(k), `no ${k} record`);
  }
});
check("the header names chronomap", () => assert.equal(reader.header.library, "chronomap"));
check("four channels with Foxglove's schema names, JSON encoded", () => {
  const topics = [...reader.channelsById.values()].map((c) => c.topic).sort();
  assert.deepEqual(topics, Object.keys(TOPICS).sort());
  for (const c of reader.channelsById.values()) {
    const s = reader.schemasById.get(c.schemaId);
    assert.equal(s.name, `foxglove.${TOPICS[c.topic]}`);
    assert.equal(s.encoding, "jsonschema");
    assert.equal(c.messageEncoding, "json");
  }
});
check("each schema is Foxglove's, field for field", () => {
  for (const c of reader.channelsById.values()) {
    const s = reader.schemasById.get(c.schemaId);
    assert.deepEqual(JSON.parse(new TextDecoder().decode(s.data)), schemas[TOPICS[c.topic]]);
  }
});

const byTopic = Object.fromEntries(Object.keys(TOPICS).map((t) => [t, []]));
for await (const m of reader.readMessages()) {
  const topic = reader.channelsById.get(m.channelId).topic;
  byTopic[topic].push({ logTime: m.logTime, message: JSON.parse(new TextDecoder().decode(m.data)) });
}
const n = sessions.length;
const expected = { "/tf": n, "/map/occupied": n, "/map/costmap": n, "/map/changes": n - 1 };
check("message counts: one per session, changes one per pair", () => {
  assert.ok(n >= 2, `the test map needs two sessions, it has ${n}`);
  for (const [topic, count] of Object.entries(expected)) assert.equal(byTopic[topic].length, count, topic);
  const channelOf = Object.fromEntries([...reader.channelsById.values()].map((c) => [c.topic, c.id]));
  assert.equal(reader.statistics.messageCount, BigInt(3 * n + n - 1));
  for (const [topic, count] of Object.entries(expected)) {
    assert.equal(reader.statistics.channelMessageCounts.get(channelOf[topic]), BigInt(count), topic);
  }
});
check("log times are the sessions' times, and each message's timestamp its log time", () => {
  for (const [topic, list] of Object.entries(byTopic)) {
    const times = topic === "/map/changes" ? sessionNs.slice(1) : sessionNs;
    list.forEach(({ logTime, message }, i) => {
      const stamp = message.timestamp ?? message.entities[0]?.timestamp ?? message.deletions[0].timestamp;
      assert.equal(BigInt(stamp.sec) * 1000000000n + BigInt(stamp.nsec), logTime, `${topic} #${i}`);
      assert.ok(logTime - times[i] <= 1000n && times[i] - logTime <= 1000n, `${topic} #${i}: ${logTime} vs ${times[i]}`);
    });
  }
  assert.equal(reader.statistics.messageStartTime, byTopic["/tf"][0].logTime);
  assert.equal(reader.statistics.messageEndTime, byTopic["/tf"][n - 1].logTime);
});
check("every message is valid under its schema", () => {
  for (const [topic, list] of Object.entries(byTopic)) {
    for (const { message } of list) validate(schemas[TOPICS[topic]], message, topic);
  }
});
check("/tf: world -> map, the identity", () => {
  const m = byTopic["/tf"][0].message;
  assert.equal(m.parent_frame_id, "world");
  assert.equal(m.child_frame_id, "map");
  assert.deepEqual(m.rotation, { x: 0, y: 0, z: 0, w: 1 });
});

// The last session's occupied voxels as `chronomap snapshot` writes them (binary PLY: x, y, z
// float, red, green, blue uchar).
function snapshotPoints(time) {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), "chronomap-foxglove-"));
  const ply = path.join(dir, "s.ply");
  run("snapshot", mapPath, "--at", String(time), "-o", ply);
  const data = fs.readFileSync(ply);
  fs.rmSync(dir, { recursive: true });
  const end = data.indexOf("end_header\n") + "end_header\n".length;
  const count = Number(/element vertex (\d+)/.exec(data.subarray(0, end).toString())[1]);
  const points = [];
  for (let i = 0; i < count; i++) {
    const o = end + 15 * i;
    points.push([data.readFloatLE(o), data.readFloatLE(o + 4), data.readFloatLE(o + 8), data[o + 12], data[o + 13], data[o + 14]].join(" "));
  }
  return points.sort();
}
check("/map/occupied: the last session's voxels in their colour, as `chronomap snapshot` writes them", () => {
  const m = byTopic["/map/occupied"][n - 1].message;
  assert.equal(m.frame_id, "map");
  assert.equal(m.point_stride, 16);
  assert.deepEqual(m.fields.map((f) => f.name), ["x", "y", "z", "red", "green", "blue", "alpha"]);
  const data = Buffer.from(m.data, "base64");
  const points = [];
  for (let o = 0; o < data.length; o += 16) {
    assert.equal(data[o + 15], 255, "alpha");
    points.push([data.readFloatLE(o), data.readFloatLE(o + 4), data.readFloatLE(o + 8), data[o + 12], data[o + 13], data[o + 14]].join(" "));
  }
  const expectedPoints = snapshotPoints(sessions[n - 1].time_s);
  assert.ok(expectedPoints.length > 100, `only ${expectedPoints.length} occupied voxels`);
  assert.deepEqual(points.sort(), expectedPoints);
  assert.ok(new Set(points.map((p) => p.split(" ").slice(3).join(" "))).size > 1, "every point has one colour");
});
check("/map/changes: per pair, the objects `chronomap diff` lists, as labelled boxes", () => {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), "chronomap-foxglove-"));
  let total = 0;
  for (let i = 1; i < n; i++) {
    const diff = JSON.parse(run("diff", `${mapPath}@${sessions[i - 1].time_s}`, `${mapPath}@${sessions[i].time_s}`,
      "-o", path.join(dir, `d${i}.cmap`), "--json"));
    const m = byTopic["/map/changes"][i - 1].message;
    assert.deepEqual(m.deletions.map((d) => d.type), [1], "the pair before's boxes are deleted first");
    assert.equal(m.entities.length, diff.objects.length, `pair ${i}`);
    diff.objects.forEach((o, k) => {
      const e = m.entities[k];
      assert.equal(e.id, `object ${o.id}`);
      assert.equal(e.metadata.find((kv) => kv.key === "kind").value, o.kind);
      assert.ok(e.texts[0].text.startsWith(`${o.id} ${o.kind}`), e.texts[0].text);
      const c = e.cubes[0];
      ["x", "y", "z"].forEach((axis, a) => {
        assert.ok(Math.abs(c.pose.position[axis] - (o.bbox_min[a] + o.bbox_max[a]) / 2) < 1e-6, `centre ${axis}`);
        assert.ok(Math.abs(c.size[axis] - (o.bbox_max[a] - o.bbox_min[a])) < 1e-6, `size ${axis}`);
      });
    });
    total += diff.objects.length;
  }
  fs.rmSync(dir, { recursive: true });
  assert.ok(total > 0, "no pair of the test map has a changed object");
});
check("/map/costmap: a grid of int8 costs, -1 .. 100, some free and some lethal", () => {
  const m = byTopic["/map/costmap"][n - 1].message;
  assert.deepEqual(m.fields, [{ name: "cost", offset: 0, type: 2 }]);
  assert.equal(m.cell_stride, 1);
  assert.equal(m.row_stride, m.column_count);
  const data = Buffer.from(m.data, "base64");
  assert.equal(data.length % m.column_count, 0);
  assert.ok(data.length / m.column_count > 1, "one row");
  const values = new Int8Array(data.buffer, data.byteOffset, data.length);
  assert.ok(values.every((v) => v >= -1 && v <= 100));
  assert.ok(values.includes(0) && values.includes(100), "no free or no lethal cell");
});
console.log(`${passed} passed, 0 failed`);
