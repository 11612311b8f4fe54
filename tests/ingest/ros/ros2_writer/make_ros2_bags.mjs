// Writes ROS 2 bags (MCAP) from a TUM RGB-D folder with the real writers: @mcap/core's McapWriter
// and @foxglove/rosmsg2-serialization's CDR MessageWriter, chunks compressed with lz4js (lz4
// frames) and @bokuweb/zstd-wasm (zstd), or stored without chunks.
//
//   node make_ros2_bags.mjs TUM_FOLDER OUT_FOLDER [NAME ...]   (the bags the tests read; only
//       these when named, as for bench/bag_vs_tum)
//   node make_ros2_bags.mjs --seeds MCAP_FOLDER CDR_FOLDER
//       (the fuzz targets' seeds: tiny bags for fuzz_mcap; for fuzz_cdr one message of each type
//       behind the byte that picks its decoder, as fuzz/fuzz_readers.cpp reads them)
//
// Like tests/ingest/ros/make_ros1_bags.py: depth stays in the TUM PNG's units (5000 per metre) in 16UC1
// images, header stamps are depth.txt's, poses are trajectory.txt's numbers.
import fs from "node:fs";
import path from "node:path";
import zlib from "node:zlib";

import { McapWriter } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageWriter } from "@foxglove/rosmsg2-serialization";
import lz4 from "lz4js";
import { init as zstdInit, compress as zstdCompress } from "@bokuweb/zstd-wasm";

// The ROS 2 interface definitions of the messages written, as `ros2 interface show` gives them
// (dependent types after a line of '='), which is also what rosbag2 stores as the schema.
const HEADER = "builtin_interfaces/Time stamp\nstring frame_id";
const TIME = "int32 sec\nuint32 nanosec";
const SEP = "\n================================================================================\n";
const dep = (name, text) => `${SEP}MSG: ${name}\n${text}`;
const TIME_HEADER = dep("std_msgs/Header", HEADER) + dep("builtin_interfaces/Time", TIME);
const POSE =
  dep("geometry_msgs/Pose", "Point position\nQuaternion orientation") +
  dep("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z") +
  dep("geometry_msgs/Quaternion", "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1");
const DEFS = {
  "sensor_msgs/msg/Image":
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data" +
    TIME_HEADER,
  "sensor_msgs/msg/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data" + TIME_HEADER,
  "sensor_msgs/msg/CameraInfo":
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\nfloat64[9] k\n" +
    "float64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\nsensor_msgs/RegionOfInterest roi" +
    TIME_HEADER +
    dep("sensor_msgs/RegionOfInterest", "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify"),
  "sensor_msgs/msg/PointCloud2":
    "std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\nbool is_bigendian\n" +
    "uint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense" +
    TIME_HEADER +
    dep("sensor_msgs/PointField", "uint8 FLOAT32 = 7\nuint8 UINT32 = 6\nstring name\nuint32 offset\nuint8 datatype\nuint32 count"),
  "geometry_msgs/msg/PoseStamped": "std_msgs/Header header\ngeometry_msgs/Pose pose" + TIME_HEADER + POSE,
  "nav_msgs/msg/Odometry":
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n" +
    "geometry_msgs/TwistWithCovariance twist" +
    TIME_HEADER +
    dep("geometry_msgs/PoseWithCovariance", "Pose pose\nfloat64[36] covariance") +
    POSE +
    dep("geometry_msgs/TwistWithCovariance", "Twist twist\nfloat64[36] covariance") +
    dep("geometry_msgs/Twist", "Vector3 linear\nVector3 angular") +
    dep("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z"),
  "tf2_msgs/msg/TFMessage":
    "geometry_msgs/TransformStamped[] transforms" +
    dep("geometry_msgs/TransformStamped", "std_msgs/Header header\nstring child_frame_id\nTransform transform") +
    TIME_HEADER +
    dep("geometry_msgs/Transform", "Vector3 translation\nQuaternion rotation") +
    dep("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z") +
    dep("geometry_msgs/Quaternion", "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1"),
};
const writers = {};
for (const [name, text] of Object.entries(DEFS)) writers[name] = new MessageWriter(parse(text, { ros2: true }));

// ---- PNG (the simulator's: 8-bit RGB/RGBA/grey or 16-bit grey, not interlaced) ----
function readPng(file) {
  const buf = fs.readFileSync(file);
  let pos = 8;
  let width = 0, height = 0, depth = 0, type = 0;
  const idat = [];
  while (pos < buf.length) {
    const len = buf.readUInt32BE(pos);
    const kind = buf.toString("latin1", pos + 4, pos + 8);
    const body = buf.subarray(pos + 8, pos + 8 + len);
    if (kind === "IHDR") {
      width = body.readUInt32BE(0);
      height = body.readUInt32BE(4);
      depth = body[8];
      type = body[9];
      if (body[12] !== 0) throw new Error(`${file}: interlaced PNG`);
    } else if (kind === "IDAT") idat.push(body);
    pos += 12 + len;
  }
  const channels = { 0: 1, 2: 3, 4: 2, 6: 4 }[type];
  const bpp = (channels * depth) / 8;
  const stride = width * bpp;
  const raw = zlib.inflateSync(Buffer.concat(idat));
  const out = Buffer.alloc(stride * height);
  for (let y = 0; y < height; y++) {
    const filter = raw[y * (stride + 1)];
    const line = raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    for (let x = 0; x < stride; x++) {
      const a = x >= bpp ? out[y * stride + x - bpp] : 0;
      const b = y > 0 ? out[(y - 1) * stride + x] : 0;
      const c = x >= bpp && y > 0 ? out[(y - 1) * stride + x - bpp] : 0;
      let v = line[x];
      if (filter === 1) v += a;
      else if (filter === 2) v += b;
      else if (filter === 3) v += (a + b) >> 1;
      else if (filter === 4) {
        const p = a + b - c, pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
        v += pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      }
      out[y * stride + x] = v & 0xff;
    }
  }
  return { width, height, depth, channels, data: out };
}

/// A PNG file of raw samples (no filter): 8-bit RGB (type 2) or 16-bit grey (type 0, big-endian
/// samples), for the fuzz targets' CompressedImage seeds.
function makePng(width, height, bitDepth, colorType, samples) {
  const crcTable = Array.from({ length: 256 }, (_, n) => {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    return c >>> 0;
  });
  const crc = (buf) => {
    let c = 0xffffffff;
    for (const b of buf) c = crcTable[(c ^ b) & 0xff] ^ (c >>> 8);
    return (c ^ 0xffffffff) >>> 0;
  };
  const chunk = (kind, body) => {
    const head = Buffer.alloc(8);
    head.writeUInt32BE(body.length, 0);
    head.write(kind, 4, "latin1");
    const tail = Buffer.alloc(4);
    tail.writeUInt32BE(crc(Buffer.concat([head.subarray(4), body])), 0);
    return Buffer.concat([head, body, tail]);
  };
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(width, 0);
  ihdr.writeUInt32BE(height, 4);
  ihdr[8] = bitDepth;
  ihdr[9] = colorType;
  const stride = samples.length / height;
  const rows = [];
  for (let y = 0; y < height; y++) rows.push(Buffer.from([0]), Buffer.from(samples.subarray(y * stride, (y + 1) * stride)));
  return Buffer.concat([Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]), chunk("IHDR", ihdr),
    chunk("IDAT", zlib.deflateSync(Buffer.concat(rows))), chunk("IEND", Buffer.alloc(0))]);
}

/// 16-bit grey as little-endian 16UC1 bytes.
function depth16(png) {
  if (png.depth !== 16 || png.channels !== 1) throw new Error("depth PNG is not 16-bit grey");
  const out = new Uint8Array(png.width * png.height * 2);
  for (let i = 0; i < png.width * png.height; i++) {
    out[2 * i] = png.data[2 * i + 1];
    out[2 * i + 1] = png.data[2 * i];
  }
  return out;
}

/// 8-bit colour as rgb8 bytes.
function rgb8(png) {
  if (png.depth !== 8) throw new Error("colour PNG is not 8-bit");
  const n = png.width * png.height, out = new Uint8Array(n * 3);
  for (let i = 0; i < n; i++) {
    for (let c = 0; c < 3; c++) out[3 * i + c] = png.data[i * png.channels + (png.channels >= 3 ? c : 0)];
  }
  return out;
}

// ---- TUM folder ----
const lines = (file) =>
  fs
    .readFileSync(file, "utf8")
    .split("\n")
    .map((l) => l.trim())
    .filter((l) => l && !l.startsWith("#"))
    .map((l) => l.split(/\s+/));

/// A ROS time from TUM's decimal seconds, exactly (no float on the way).
function stampOf(text) {
  const [whole, frac = ""] = text.split(".");
  return { sec: Number(whole), nanosec: Number((frac + "000000000").slice(0, 9)) };
}
const nanos = (s) => BigInt(s.sec) * 1000000000n + BigInt(s.nanosec);
const fromNanos = (n) => ({ sec: Number(n / 1000000000n), nanosec: Number(n % 1000000000n) });

function load(tum) {
  const intr = fs.readFileSync(path.join(tum, "camera-intrinsics.txt"), "utf8").trim().split(/\s+/).map(Number);
  const colors = new Map(lines(path.join(tum, "rgb.txt")).map(([t, n]) => [t, n]));
  const poses = new Map(lines(path.join(tum, "trajectory.txt")).map((r) => [r[0], r.slice(1).map(Number)]));
  const frames = lines(path.join(tum, "depth.txt")).map(([t, name]) => {
    const depth = readPng(path.join(tum, name));
    const rgb = readPng(path.join(tum, colors.get(t)));
    const p = poses.get(t);
    return {
      stamp: stampOf(t),
      width: depth.width,
      height: depth.height,
      depth: depth16(depth),
      rgb: rgb8(rgb),
      // The PNG files themselves, for the CompressedImage bags (lossless: the same map).
      depthPng: fs.readFileSync(path.join(tum, name)),
      rgbPng: fs.readFileSync(path.join(tum, colors.get(t))),
      pose: [p.slice(0, 3), p.slice(3, 7)],
    };
  });
  return { intr, frames };
}

// ---- poses (as make_ros1_bags.py) ----
const quatMul = ([ax, ay, az, aw], [bx, by, bz, bw]) => [
  aw * bx + ax * bw + ay * bz - az * by,
  aw * by - ax * bz + ay * bw + az * bx,
  aw * bz + ax * by - ay * bx + az * bw,
  aw * bw - ax * bx - ay * by - az * bz,
];
const rotate = (q, v) => quatMul(quatMul(q, [v[0], v[1], v[2], 0]), [-q[0], -q[1], -q[2], q[3]]).slice(0, 3);
const normalized = ([t, q]) => {
  const n = Math.sqrt(q.reduce((s, v) => s + v * v, 0));
  return [t, q.map((v) => v / n)];
};
const compose = ([ta, qa], [tb, qb]) => {
  const r = rotate(qa, tb);
  return [[ta[0] + r[0], ta[1] + r[1], ta[2] + r[2]], quatMul(qa, qb)];
};
const inverse = ([t, q]) => {
  const qi = [-q[0], -q[1], -q[2], q[3]];
  const r = rotate(qi, t);
  return [[-r[0], -r[1], -r[2]], qi];
};
const T_BASE_CAMERA = [[0.1, -0.02, 1.2], [-0.5, 0.5, -0.5, 0.5]];
const T_MAP_ODOM = [[0.5, -0.25, 0.0], [0.0, 0.0, Math.sin(0.05), Math.cos(0.05)]];
const TF_OFFSET_NS = 10000000n; // /tf samples 10 ms before and after each frame

// ---- messages ----
const header = (stamp, frame_id) => ({ stamp, frame_id });
const image = (stamp, frame, width, height, encoding, bytesPerPixel, data) => ({
  header: header(stamp, frame),
  height,
  width,
  encoding,
  is_bigendian: 0,
  step: width * bytesPerPixel,
  data,
});
const info = (stamp, frame, [fx, fy, cx, cy], width, height) => ({
  header: header(stamp, frame),
  height,
  width,
  distortion_model: "plumb_bob",
  d: [0, 0, 0, 0, 0],
  k: [fx, 0, cx, 0, fy, cy, 0, 0, 1],
  r: [1, 0, 0, 0, 1, 0, 0, 0, 1],
  p: [fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0],
  binning_x: 0,
  binning_y: 0,
  roi: { x_offset: 0, y_offset: 0, height: 0, width: 0, do_rectify: false },
});
/// sensor_msgs/CompressedImage as image_transport's plugins write it: the compressed transport's
/// PNG, and compressedDepth's 12-byte header (compression 0, two quantisation floats unused for
/// 16UC1) before a 16-bit PNG.
const compressed = (stamp, frame, format, data) => ({ header: header(stamp, frame), format, data });
const depthHeader = Buffer.alloc(12);
const point = ([x, y, z]) => ({ x, y, z });
const quat = ([x, y, z, w]) => ({ x, y, z, w });
const transform = (stamp, parent, child, [t, q]) => ({
  header: header(stamp, parent),
  child_frame_id: child,
  transform: { translation: point(t), rotation: quat(q) },
});
const zeros36 = new Array(36).fill(0);
const odometry = (stamp, child, [t, q]) => ({
  header: header(stamp, "map"),
  child_frame_id: child,
  pose: { pose: { position: point(t), orientation: quat(q) }, covariance: zeros36 },
  twist: { twist: { linear: point([0, 0, 0]), angular: point([0, 0, 0]) }, covariance: zeros36 },
});

/// The depth image back-projected as the TUM reader does (x, y, z FLOAT32, NaN without depth),
/// with colour packed as 0x00RRGGBB in an `rgb` field, as make_ros1_bags.py writes it.
function cloud(stamp, frame, f, [fx, fy, cx, cy]) {
  const n = f.width * f.height, data = new Uint8Array(16 * n), view = new DataView(data.buffer);
  for (let v = 0; v < f.height; v++) {
    for (let u = 0; u < f.width; u++) {
      const i = v * f.width + u, raw = f.depth[2 * i] | (f.depth[2 * i + 1] << 8), z = raw / 5000.0;
      view.setFloat32(16 * i, raw > 0 ? ((u - cx) * z) / fx : NaN, true);
      view.setFloat32(16 * i + 4, raw > 0 ? ((v - cy) * z) / fy : NaN, true);
      view.setFloat32(16 * i + 8, raw > 0 ? z : NaN, true);
      view.setUint32(16 * i + 12, (f.rgb[3 * i] << 16) | (f.rgb[3 * i + 1] << 8) | f.rgb[3 * i + 2], true);
    }
  }
  const field = (name, offset) => ({ name, offset, datatype: 7, count: 1 });
  return {
    header: header(stamp, frame),
    height: f.height,
    width: f.width,
    fields: [field("x", 0), field("y", 4), field("z", 8), field("rgb", 12)],
    is_bigendian: false,
    point_step: 16,
    row_step: 16 * f.width,
    data,
    is_dense: false,
  };
}

/// An in-memory IWritable.
class Sink {
  constructor() {
    this.parts = [];
    this.size = 0n;
  }
  position() {
    return this.size;
  }
  async write(buffer) {
    this.parts.push(Buffer.from(buffer));
    this.size += BigInt(buffer.byteLength);
  }
}

const COMPRESSORS = {
  none: undefined,
  lz4: (data) => ({ compression: "lz4", compressedData: lz4.compress(data) }),
  zstd: (data) => ({ compression: "zstd", compressedData: zstdCompress(data, 3) }),
};

async function write(file, intr, frames, { storage = "lz4", pose = "pose_stamped", summary = true, chunkSize = 64 * 1024, points = false, tfStatic = true, compressedImages = false } = {}) {
  const sink = new Sink();
  const chunked = storage !== "unchunked";
  const writer = new McapWriter({
    writable: sink,
    useChunks: chunked,
    chunkSize,
    compressChunk: chunked ? COMPRESSORS[storage] : undefined,
    useStatistics: summary,
    useSummaryOffsets: summary,
    useChunkIndex: summary,
    useMessageIndex: summary,
    repeatSchemas: summary,
    repeatChannels: summary,
  });
  await writer.start({ profile: "ros2", library: "chronomap tests (@mcap/core)" });
  const channels = {};
  async function publish(topic, type, msg, stamp) {
    if (!(topic in channels)) {
      const schemaId = await writer.registerSchema({ name: type, encoding: "ros2msg", data: new TextEncoder().encode(DEFS[type]) });
      channels[topic] = await writer.registerChannel({ topic, schemaId, messageEncoding: "cdr", metadata: new Map() });
    }
    const t = nanos(stamp);
    await writer.addMessage({ channelId: channels[topic], sequence: 0, logTime: t, publishTime: t, data: writers[type].writeMessage(msg) });
  }
  const camera = "camera_depth_optical_frame";
  if (pose === "tf" && tfStatic) {
    await publish("/tf_static", "tf2_msgs/msg/TFMessage", {
      transforms: [transform(frames[0].stamp, "base_link", camera, T_BASE_CAMERA), transform(frames[0].stamp, "map", "odom", T_MAP_ODOM)],
    }, frames[0].stamp);
  }
  for (const f of frames) {
    const s = f.stamp;
    if (points) {
      await publish("/camera/depth/points", "sensor_msgs/msg/PointCloud2", cloud(s, camera, f, intr), s);
    } else if (compressedImages) {
      await publish("/camera/depth/image_raw/compressedDepth", "sensor_msgs/msg/CompressedImage",
        compressed(s, camera, "16UC1; compressedDepth png", Buffer.concat([depthHeader, f.depthPng])), s);
      await publish("/camera/depth/camera_info", "sensor_msgs/msg/CameraInfo", info(s, camera, intr, f.width, f.height), s);
      await publish("/camera/rgb/image_raw/compressed", "sensor_msgs/msg/CompressedImage",
        compressed(s, "camera_rgb_optical_frame", "rgb8; png compressed bgr8", f.rgbPng), s);
    } else {
      await publish("/camera/depth/image_raw", "sensor_msgs/msg/Image", image(s, camera, f.width, f.height, "16UC1", 2, f.depth), s);
      await publish("/camera/depth/camera_info", "sensor_msgs/msg/CameraInfo", info(s, camera, intr, f.width, f.height), s);
      await publish("/camera/rgb/image_raw", "sensor_msgs/msg/Image", image(s, "camera_rgb_optical_frame", f.width, f.height, "rgb8", 3, f.rgb), s);
    }
    if (pose === "pose_stamped") {
      await publish("/camera_pose", "geometry_msgs/msg/PoseStamped", {
        header: header(s, "map"),
        pose: { position: point(f.pose[0]), orientation: quat(f.pose[1]) },
      }, s);
    } else if (pose === "odometry") {
      await publish("/odom", "nav_msgs/msg/Odometry", odometry(s, camera, f.pose), s);
    } else if (pose === "tf") {
      const T_odom_base = compose(compose(inverse(T_MAP_ODOM), normalized(f.pose)), inverse(T_BASE_CAMERA));
      for (const offset of [-TF_OFFSET_NS, TF_OFFSET_NS]) {
        const t = fromNanos(nanos(s) + offset);
        await publish("/tf", "tf2_msgs/msg/TFMessage", { transforms: [transform(t, "odom", "base_link", T_odom_base)] }, t);
      }
    }
  }
  await writer.end();
  fs.writeFileSync(file, Buffer.concat(sink.parts));
}

async function main() {
  await zstdInit();
  const args = process.argv.slice(2);
  if (args[0] === "--seeds") {
    // Three 8 x 6 frames (a wall 1 m away), small enough for the fuzzer's 64 KiB.
    const out = args[1];
    fs.mkdirSync(out, { recursive: true });
    const frames = [0, 1, 2].map((i) => {
      const depth = new Uint8Array(8 * 6 * 2);
      for (let p = 1; p < 48; p++) {
        depth[2 * p] = 5000 & 0xff;
        depth[2 * p + 1] = 5000 >> 8;
      }
      return { stamp: { sec: 100 + i, nanosec: 0 }, width: 8, height: 6, depth, rgb: new Uint8Array(8 * 6 * 3).fill(40 * i), pose: [[0.1 * i, 0, 0], [0, 0, 0, 1]] };
    });
    const intr = [8, 8, 3.5, 2.5];
    await write(path.join(out, "unchunked.mcap"), intr, frames, { storage: "unchunked", summary: false });
    await write(path.join(out, "lz4.mcap"), intr, frames, { storage: "lz4", chunkSize: 512 });
    await write(path.join(out, "zstd.mcap"), intr, frames, { storage: "zstd", pose: "tf" });
    await write(path.join(out, "odometry.mcap"), intr, frames, { storage: "none", pose: "odometry" });
    await write(path.join(out, "points.mcap"), intr, frames, { storage: "lz4", points: true });
    const cdr = args[2];
    fs.mkdirSync(cdr, { recursive: true });
    const f = frames[1], s = f.stamp;
    const seed = (name, selector, type, msg) =>
      fs.writeFileSync(path.join(cdr, name), Buffer.concat([Buffer.from([selector]), writers[type].writeMessage(msg)]));
    seed("color", 0, "sensor_msgs/msg/Image", image(s, "cam", 8, 6, "rgb8", 3, f.rgb));
    seed("depth", 1, "sensor_msgs/msg/Image", image(s, "cam", 8, 6, "16UC1", 2, f.depth));
    seed("cloud", 2, "sensor_msgs/msg/PointCloud2", cloud(s, "cam", f, intr));
    seed("info", 3, "sensor_msgs/msg/CameraInfo", info(s, "cam", intr, 8, 6));
    seed("tf", 4, "tf2_msgs/msg/TFMessage", { transforms: [transform(s, "map", "cam", f.pose), transform(s, "odom", "base", f.pose)] });
    seed("odometry", 5, "nav_msgs/msg/Odometry", odometry(s, "cam", f.pose));
    seed("pose", 6, "geometry_msgs/msg/PoseStamped", { header: header(s, "map"), pose: { position: point(f.pose[0]), orientation: quat(f.pose[1]) } });
    const bigEndian = Buffer.from(f.depth);
    for (let i = 0; i < bigEndian.length; i += 2) [bigEndian[i], bigEndian[i + 1]] = [bigEndian[i + 1], bigEndian[i]];
    seed("compressed_color", 7, "sensor_msgs/msg/CompressedImage", compressed(s, "cam", "rgb8; png compressed bgr8", makePng(8, 6, 8, 2, f.rgb)));
    seed("compressed_depth", 8, "sensor_msgs/msg/CompressedImage",
      compressed(s, "cam", "16UC1; compressedDepth png", Buffer.concat([depthHeader, makePng(8, 6, 16, 0, bigEndian)])));
    return;
  }
  const [tum, out, ...only] = args;
  fs.mkdirSync(out, { recursive: true });
  const { intr, frames } = load(tum);
  const bags = {
    "pose_unchunked.mcap": { storage: "unchunked" },
    "pose_unchunked_nosummary.mcap": { storage: "unchunked", summary: false },
    "pose_none.mcap": { storage: "none" },
    "pose_lz4.mcap": { storage: "lz4" },
    "pose_zstd.mcap": { storage: "zstd" },
    "pose_zstd_nosummary.mcap": { storage: "zstd", summary: false },
    "odometry.mcap": { storage: "zstd", pose: "odometry" },
    "tf.mcap": { storage: "lz4", pose: "tf" },
    "points.mcap": { storage: "zstd", points: true },
    "compressed.mcap": { storage: "lz4", compressedImages: true },
  };
  for (const [name, options] of Object.entries(bags)) {
    if (only.length === 0 || only.includes(name)) await write(path.join(out, name), intr, frames, options);
  }
  if (only.length > 0 && !only.includes("split_tf")) return;
  // A bag split as rosbag2 splits a recording (--max-bag-size): a folder of three storage files
  // in time order, each with its own schemas and channels, /tf_static only in the first, and
  // metadata.yaml listing them.
  const split = path.join(out, "split_tf");
  fs.mkdirSync(split, { recursive: true });
  const parts = [frames.slice(0, 11), frames.slice(11, 22), frames.slice(22)];
  const names = parts.map((_, i) => `split_tf_${i}.mcap`);
  for (let i = 0; i < parts.length; i++) {
    await write(path.join(split, names[i]), intr, parts[i], { storage: i === 1 ? "zstd" : "lz4", pose: "tf", tfStatic: i === 0 });
  }
  fs.writeFileSync(path.join(split, "metadata.yaml"), [
    "rosbag2_bagfile_information:",
    "  version: 8",
    "  storage_identifier: mcap",
    "  relative_file_paths:",
    ...names.map((n) => `    - ${n}`),
    "  duration:",
    "    nanoseconds: 3100000000",
    "",
  ].join("\n"));
}

main().catch((e) => {
  console.error(e.stack || String(e));
  process.exit(1);
});
