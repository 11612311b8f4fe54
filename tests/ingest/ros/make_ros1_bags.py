#!/usr/bin/python3
"""Writes ROS 1 bags from a TUM RGB-D folder with Debian's python3-rosbag, for the bag tests.

    /usr/bin/python3 make_ros1_bags.py TUM_FOLDER OUT_FOLDER [NAME.bag ...]   (only these)
    /usr/bin/python3 make_ros1_bags.py --3dmatch SEQUENCE_FOLDER INTRINSICS_FILE OUT.bag
    /usr/bin/python3 make_ros1_bags.py --seeds OUT_FOLDER   (tiny bags: the fuzz target's seeds)

Every bag holds the folder's frames with the header stamps of depth.txt; what differs is how
(see the table in main()). Depth stays in the TUM PNG's units (5000 per metre) in 16UC1 bags,
so the tests read them with --depth-scale 5000 and get the TUM reader's numbers exactly.
"""
import io
import math
import os
import struct
import sys

import numpy as np
import rosbag
import genpy
from PIL import Image as PilImage
from geometry_msgs.msg import PoseStamped, TransformStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2, PointField
from tf2_msgs.msg import TFMessage


def read_list(path):
    out = []
    for line in open(path):
        line = line.strip()
        if line and not line.startswith('#'):
            out.append(line.split())
    return out


def stamp_of(text):
    """A ROS time from TUM's decimal seconds, exactly (no float on the way)."""
    whole, _, frac = text.partition('.')
    return genpy.Time(int(whole), int((frac + '000000000')[:9]))


def quat_mul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def rotate(q, v):
    x, y, z, w = quat_mul(quat_mul(q, (v[0], v[1], v[2], 0.0)), (-q[0], -q[1], -q[2], q[3]))
    return (x, y, z)


def normalized(pose):
    t, q = pose
    n = math.sqrt(sum(v * v for v in q))
    return (t, tuple(v / n for v in q))


def compose(a, b):
    """(t, q) of a * b."""
    ta, qa = a
    tb, qb = b
    r = rotate(qa, tb)
    return ((ta[0] + r[0], ta[1] + r[1], ta[2] + r[2]), quat_mul(qa, qb))


def inverse(a):
    t, q = a
    qi = (-q[0], -q[1], -q[2], q[3])
    r = rotate(qi, t)
    return ((-r[0], -r[1], -r[2]), qi)


def load(tum):
    intr = [float(v) for v in open(os.path.join(tum, 'camera-intrinsics.txt')).read().split()]
    depths = read_list(os.path.join(tum, 'depth.txt'))
    colors = {t: name for t, name in read_list(os.path.join(tum, 'rgb.txt'))}
    poses = {row[0]: ((float(row[1]), float(row[2]), float(row[3])), tuple(float(v) for v in row[4:8]))
             for row in read_list(os.path.join(tum, 'trajectory.txt'))}
    frames = []
    for t, name in depths:
        depth = np.array(PilImage.open(os.path.join(tum, name))).astype(np.uint16)
        rgb = np.array(PilImage.open(os.path.join(tum, colors[t])).convert('RGB')).astype(np.uint8)
        frames.append({'text': t, 'stamp': stamp_of(t), 'depth': depth, 'rgb': rgb, 'pose': poses[t],
                       # the PNG files themselves, for the CompressedImage bags (lossless: the same map)
                       'depth_png': open(os.path.join(tum, name), 'rb').read(),
                       'rgb_png': open(os.path.join(tum, colors[t]), 'rb').read()})
    return intr, frames


def header(msg, stamp, frame):
    msg.header.stamp = stamp
    msg.header.frame_id = frame
    return msg


def image(stamp, frame, array, encoding):
    m = header(Image(), stamp, frame)
    m.height, m.width = array.shape[0], array.shape[1]
    m.encoding = encoding
    m.is_bigendian = 0
    m.step = array.strides[0]
    m.data = array.tobytes()
    return m


def compressed(stamp, frame, fmt, data):
    """sensor_msgs/CompressedImage as image_transport's plugins write it."""
    m = header(CompressedImage(), stamp, frame)
    m.format = fmt
    m.data = data
    return m


# compressedDepth's header before its PNG: the compression (0) and two quantisation floats,
# unused for 16UC1.
DEPTH_HEADER = struct.pack('<iff', 0, 0.0, 0.0)


def jpeg(rgb):
    out = io.BytesIO()
    PilImage.fromarray(rgb, 'RGB').save(out, format='JPEG', quality=90)
    return out.getvalue()


def info(stamp, frame, intr, shape):
    fx, fy, cx, cy = intr
    m = header(CameraInfo(), stamp, frame)
    m.height, m.width = shape[0], shape[1]
    m.distortion_model = 'plumb_bob'
    m.D = [0.0] * 5
    m.K = [fx, 0, cx, 0, fy, cy, 0, 0, 1]
    m.R = [1, 0, 0, 0, 1, 0, 0, 0, 1]
    m.P = [fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0]
    return m


def transform(stamp, parent, child, pose):
    ts = TransformStamped()
    ts.header.stamp = stamp
    ts.header.frame_id = parent
    ts.child_frame_id = child
    (ts.transform.translation.x, ts.transform.translation.y, ts.transform.translation.z) = pose[0]
    (ts.transform.rotation.x, ts.transform.rotation.y, ts.transform.rotation.z, ts.transform.rotation.w) = pose[1]
    return ts


def cloud(stamp, frame, depth, rgb, intr, scale):
    """The depth image back-projected as the TUM reader does, with packed rgb."""
    fx, fy, cx, cy = intr
    h, w = depth.shape
    z = depth.astype(np.float64) / scale
    u, v = np.meshgrid(np.arange(w), np.arange(h))
    pts = np.zeros((h, w), dtype=[('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('rgb', '<u4')])
    pts['x'] = np.where(depth > 0, (u - cx) * z / fx, np.nan)
    pts['y'] = np.where(depth > 0, (v - cy) * z / fy, np.nan)
    pts['z'] = np.where(depth > 0, z, np.nan)
    pts['rgb'] = (rgb[:, :, 0].astype(np.uint32) << 16) | (rgb[:, :, 1].astype(np.uint32) << 8) | rgb[:, :, 2]
    m = header(PointCloud2(), stamp, frame)
    m.height, m.width = h, w
    m.fields = [PointField('x', 0, PointField.FLOAT32, 1), PointField('y', 4, PointField.FLOAT32, 1),
                PointField('z', 8, PointField.FLOAT32, 1), PointField('rgb', 12, PointField.FLOAT32, 1)]
    m.is_bigendian = False
    m.point_step = 16
    m.row_step = 16 * w
    m.data = pts.tobytes()
    m.is_dense = False
    return m


# The robot's body and its camera, fixed to it (for the /tf bags).
T_BASE_CAMERA = ((0.1, -0.02, 1.2), (-0.5, 0.5, -0.5, 0.5))
T_MAP_ODOM = ((0.5, -0.25, 0.0), (0.0, 0.0, math.sin(0.05), math.cos(0.05)))
TF_OFFSET_NS = 10_000_000  # /tf samples 10 ms before and after each frame


def write(path, intr, frames, compression='none', pose='pose_stamped', depth='16UC1', color='rgb8',
          drop_pose=(), nan_rows=0, points=False, extra_depth=False, both_colors=False, info_scale=1):
    bag = rosbag.Bag(path, 'w', compression=compression)
    camera = 'camera_depth_optical_frame'
    try:
        if pose in ('tf', 'odometry_base'):
            static = TFMessage([transform(frames[0]['stamp'], 'base_link', camera, T_BASE_CAMERA),
                                transform(frames[0]['stamp'], 'map', 'odom', T_MAP_ODOM)])
            bag.write('/tf_static', static, frames[0]['stamp'])
        for i, f in enumerate(frames):
            s = f['stamp']
            if points:
                bag.write('/camera/depth/points', cloud(s, camera, f['depth'], f['rgb'], intr, 5000.0), s)
            else:
                if depth == '16UC1':
                    bag.write('/camera/depth/image_raw', image(s, camera, f['depth'], '16UC1'), s)
                elif depth == 'compressedDepth':
                    bag.write('/camera/depth/image_raw/compressedDepth',
                              compressed(s, camera, '16UC1; compressedDepth png', DEPTH_HEADER + f['depth_png']), s)
                else:
                    metres = (f['depth'].astype(np.float32) / np.float32(5000.0)).astype('<f4')
                    metres[metres == 0] = np.nan
                    metres[:nan_rows, :] = np.nan
                    bag.write('/camera/depth/image_raw', image(s, camera, metres, '32FC1'), s)
                if extra_depth:
                    bag.write('/camera2/depth/image_raw', image(s, camera, f['depth'], '16UC1'), s)
                # info_scale: a CameraInfo for images that many times larger (another resolution mode)
                shape = tuple(n * info_scale for n in f['depth'].shape)
                scaled = tuple(v * info_scale for v in intr)
                bag.write('/camera/depth/camera_info', info(s, camera, scaled, shape), s)
                rgb_frame = 'camera_rgb_optical_frame'
                if color in ('png', 'jpeg'):
                    data = f['rgb_png'] if color == 'png' else jpeg(f['rgb'])
                    bag.write('/camera/rgb/image_raw/compressed',
                              compressed(s, rgb_frame, 'rgb8; %s compressed bgr8' % color, data), s)
                if color != 'png' and color != 'jpeg' or both_colors:
                    # raw colour (beside the compressed transport when both_colors)
                    raw = color if color in ('rgb8', 'bgr8') else 'rgb8'
                    rgb = f['rgb'] if raw == 'rgb8' else np.ascontiguousarray(f['rgb'][:, :, ::-1])
                    bag.write('/camera/rgb/image_raw', image(s, rgb_frame, rgb, raw), s)
            if i in drop_pose:
                continue
            if pose == 'pose_stamped':
                m = header(PoseStamped(), s, 'map')
                (m.pose.position.x, m.pose.position.y, m.pose.position.z) = f['pose'][0]
                (m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z, m.pose.orientation.w) = f['pose'][1]
                bag.write('/camera_pose', m, s)
            elif pose == 'odometry':
                m = header(Odometry(), s, 'map')
                m.child_frame_id = camera
                (m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z) = f['pose'][0]
                (m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z,
                 m.pose.pose.orientation.w) = f['pose'][1]
                bag.write('/odom', m, s)
            elif pose == 'odometry_base':
                # The robot's body in the map; the camera hangs off it through /tf_static.
                T_map_base = compose(normalized(f['pose']), inverse(T_BASE_CAMERA))
                m = header(Odometry(), s, 'map')
                m.child_frame_id = 'base_link'
                (m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z) = T_map_base[0]
                (m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z,
                 m.pose.pose.orientation.w) = T_map_base[1]
                bag.write('/odom', m, s)
            elif pose == 'tf':
                # map -> odom is static; odom -> base_link from the camera's pose, sampled 10 ms
                # before and after the frame (the same pose at both, so interpolation keeps it).
                T_odom_base = compose(compose(inverse(T_MAP_ODOM), normalized(f['pose'])), inverse(T_BASE_CAMERA))
                for offset in (-TF_OFFSET_NS, TF_OFFSET_NS):
                    t = s + genpy.Duration(0, offset)
                    bag.write('/tf', TFMessage([transform(t, 'odom', 'base_link', T_odom_base)]), t)
    finally:
        bag.close()


def quaternion_of(r):
    """(x, y, z, w) of a rotation matrix, by the branches Eigen's Quaternion(Matrix3) takes."""
    q = [0.0, 0.0, 0.0, 0.0]
    t = r[0][0] + r[1][1] + r[2][2]
    if t > 0:
        t = math.sqrt(t + 1.0)
        q[3] = 0.5 * t
        t = 0.5 / t
        q[0] = (r[2][1] - r[1][2]) * t
        q[1] = (r[0][2] - r[2][0]) * t
        q[2] = (r[1][0] - r[0][1]) * t
    else:
        i = 0
        if r[1][1] > r[0][0]:
            i = 1
        if r[2][2] > r[i][i]:
            i = 2
        j, k = (i + 1) % 3, (i + 2) % 3
        t = math.sqrt(r[i][i] - r[j][j] - r[k][k] + 1.0)
        q[i] = 0.5 * t
        t = 0.5 / t
        q[3] = (r[k][j] - r[j][k]) * t
        q[j] = (r[j][i] + r[i][j]) * t
        q[k] = (r[k][i] + r[i][k]) * t
    return tuple(q)


def write_3dmatch(seq, intrinsics, out):
    """A 3DMatch sequence as a bag: depth 16UC1 in millimetres (as REP 118 and 3DMatch store it),
    colour rgb8, CameraInfo, and the camera-to-world matrices as PoseStamped."""
    k = [float(v) for v in open(intrinsics).read().split()]
    intr = (k[0], k[4], k[2], k[5])
    names = sorted(n[:-len('.depth.png')] for n in os.listdir(seq) if n.endswith('.depth.png'))
    camera = 'camera_depth_optical_frame'
    bag = rosbag.Bag(out, 'w', compression='lz4')
    try:
        for i, name in enumerate(names):
            s = genpy.Time(1000 + i, 0)
            depth = np.array(PilImage.open(os.path.join(seq, name + '.depth.png'))).astype(np.uint16)
            rgb = np.array(PilImage.open(os.path.join(seq, name + '.color.png')).convert('RGB')).astype(np.uint8)
            m = [[float(v) for v in line.split()] for line in open(os.path.join(seq, name + '.pose.txt')) if line.strip()]
            bag.write('/camera/depth/image_raw', image(s, camera, depth, '16UC1'), s)
            bag.write('/camera/depth/camera_info', info(s, camera, intr, depth.shape), s)
            bag.write('/camera/rgb/image_raw', image(s, camera, rgb, 'rgb8'), s)
            p = header(PoseStamped(), s, 'map')
            (p.pose.position.x, p.pose.position.y, p.pose.position.z) = (m[0][3], m[1][3], m[2][3])
            (p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z, p.pose.orientation.w) = quaternion_of(m)
            bag.write('/camera_pose', p, s)
    finally:
        bag.close()


def write_seeds(out):
    """Bags of three 8 x 6 frames (a wall 1 m away), small enough for the fuzzer's 64 KiB."""
    os.makedirs(out, exist_ok=True)
    frames = []
    for i in range(3):
        depth = np.full((6, 8), 5000, dtype=np.uint16)
        depth[0, 0] = 0
        rgb = np.full((6, 8, 3), 40 * i, dtype=np.uint8)
        frames.append({'stamp': genpy.Time(100 + i, 0), 'depth': depth, 'rgb': rgb,
                       'pose': ((0.1 * i, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))})
    intr = (8.0, 8.0, 3.5, 2.5)
    for name, options in {'none.bag': {}, 'bz2.bag': dict(compression='bz2'), 'lz4.bag': dict(compression='lz4'),
                          'tf.bag': dict(pose='tf'), 'float.bag': dict(depth='32FC1', color='bgr8'),
                          'points.bag': dict(points=True, pose='odometry'), 'jpeg.bag': dict(color='jpeg')}.items():
        write(os.path.join(out, name), intr, frames, **options)


def main():
    if sys.argv[1] == '--seeds':
        write_seeds(sys.argv[2])
        return
    if sys.argv[1] == '--3dmatch':
        write_3dmatch(sys.argv[2], sys.argv[3], sys.argv[4])
        return
    tum, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    intr, frames = load(tum)
    # Simulated time: the recording starts at time 0 (stamps and bag times), its /tf_static at 0.
    zero = genpy.Time(0, 0)
    from_zero = [dict(f, stamp=zero + (f['stamp'] - frames[0]['stamp'])) for f in frames]
    # name: how the frames are stored
    bags = {
        'pose_none.bag': dict(compression='none'),
        'pose_bz2.bag': dict(compression='bz2'),
        'pose_lz4.bag': dict(compression='lz4'),
        'odometry.bag': dict(pose='odometry', compression='lz4'),
        'tf.bag': dict(pose='tf', compression='lz4'),
        'odometry_base.bag': dict(pose='odometry_base'),
        'tf_gaps.bag': dict(pose='tf', drop_pose=(3, 7, 8)),
        'float_bgr.bag': dict(depth='32FC1', color='bgr8'),
        'float_nan.bag': dict(depth='32FC1', nan_rows=frames[0]['depth'].shape[0] // 2),
        'points.bag': dict(points=True),
        'two_depths.bag': dict(extra_depth=True),
        'no_pose.bag': dict(pose='none'),
        # sensor_msgs/CompressedImage: compressedDepth and PNG colour (lossless), JPEG colour,
        # and JPEG colour beside the raw topic (the raw one is read)
        'compressed_png.bag': dict(depth='compressedDepth', color='png', compression='lz4'),
        'compressed_jpeg.bag': dict(color='jpeg'),
        'raw_and_jpeg.bag': dict(color='jpeg', both_colors=True),
        'info_640.bag': dict(info_scale=4),
    }
    only = sys.argv[3:]
    for name, options in bags.items():
        if not only or name in only:
            write(os.path.join(out, name), intr, frames, **options)
    if not only or 'sim_time.bag' in only:
        write(os.path.join(out, 'sim_time.bag'), intr, from_zero, pose='odometry_base')


if __name__ == '__main__':
    main()
