#!/usr/bin/python3
"""ROS 1 bags against Debian's own ROS tools (issue 27, item 3).

Export: every kind of ROS 1 bag `sonar3d export rosbag --ros1` writes (16- and 8-bit frames, chunks
uncompressed, bz2 and lz4, both message packages) opens in Debian's `rosbag` Python API and passes
`rosbag info`: topics, types, counts, MD5 sums (as genpy computes them from the stored definitions
and as the installed nav_msgs/tf2_msgs packages state them), latching of /tf_static, stamps, poses,
the mounting and every image against the dataset.

Import: bags written by Debian's `rosbag` Python API with the installed message classes —
sensor_msgs/Image + nav_msgs/Odometry, sensor_msgs/Image + geometry_msgs/PoseStamped, mountings on
/tf_static (one or several latched broadcasters, ROS 1's leading-slash frame names), chunks
uncompressed, bz2 and lz4 — import with `sonar3d import rosbag`: frame count, stamps, image content,
navigation and mounting are asserted. A bag re-recorded by rosbag from sonar3d's own export
(ProjectedSonarImage serialized by genpy) imports to the original dataset.

Run by ctest as `/usr/bin/python3 test_rosbag_debian.py SONAR3D_CLI`. Needs python3-rosbag,
python3-sensor-msgs, python3-nav-msgs, python3-geometry-msgs, python3-tf2-msgs (installed by
scripts/install-deps.sh) and numpy.
"""
import math
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import unittest
import zlib

import numpy as np
import yaml

try:
    import genpy
    import genpy.dynamic
    import rosbag
    import rospy
    from geometry_msgs.msg import PoseStamped, TransformStamped
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import Image
    from tf2_msgs.msg import TFMessage
except ImportError as e:
    sys.exit(f'test_rosbag_debian: {e}: Debian\'s ROS 1 Python packages are missing '
             '(python3-rosbag, python3-sensor-msgs, python3-nav-msgs, python3-geometry-msgs, '
             'python3-tf2-msgs); run scripts/install-deps.sh')

CLI = None
WORK = None
ROSBAG_CLI = shutil.which('rosbag') or '/usr/bin/rosbag'


# ------------------------------------------------------------------------------------- helpers

def run(*args, ok=True):
    p = subprocess.run([CLI, *args], capture_output=True, text=True)
    if ok and p.returncode != 0:
        raise AssertionError(f'sonar3d {" ".join(args)} failed ({p.returncode}):\n{p.stderr}')
    return p


def read_png(path):
    """A grayscale, non-interlaced 8/16-bit PNG (the dataset's frames) as a numpy array."""
    with open(path, 'rb') as f:
        data = f.read()
    assert data[:8] == b'\x89PNG\r\n\x1a\n', path
    pos, idat = 8, b''
    while pos < len(data):
        n, kind = struct.unpack('>I4s', data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        pos += 12 + n
        if kind == b'IHDR':
            w, h, depth, ctype, _, _, interlace = struct.unpack('>IIBBBBB', body)
        elif kind == b'IDAT':
            idat += body
        elif kind == b'IEND':
            break
    assert ctype == 0 and interlace == 0 and depth in (8, 16), (path, ctype, depth)
    bpp = depth // 8
    stride = w * bpp
    raw = zlib.decompress(idat)
    rows = np.frombuffer(raw, np.uint8).reshape(h, stride + 1)
    out = np.zeros((h, stride), np.int32)
    prev = np.zeros(stride, np.int32)
    for y in range(h):
        f, line = rows[y, 0], rows[y, 1:].astype(np.int32)
        if f == 0:
            cur = line
        elif f == 2:
            cur = (line + prev) & 255
        else:  # Sub, Average, Paeth depend on the reconstructed left neighbour: byte by byte
            cur = np.zeros(stride, np.int32)
            for i in range(stride):
                a = cur[i - bpp] if i >= bpp else 0
                b = prev[i]
                c = prev[i - bpp] if i >= bpp else 0
                if f == 1:
                    pr = a
                elif f == 3:
                    pr = (a + b) // 2
                else:
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    pr = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                cur[i] = (line[i] + pr) & 255
        out[y] = cur
        prev = cur
    b = out.astype(np.uint8).tobytes()
    return np.frombuffer(b, '>u2' if depth == 16 else np.uint8).reshape(h, w).astype(
        np.uint16 if depth == 16 else np.uint8)


def read_dataset(d):
    with open(os.path.join(d, 'sonar.yaml')) as f:
        sensor = yaml.safe_load(f)['sensor']
    with open(os.path.join(d, 'frames.csv')) as f:
        lines = f.read().split('\n')[1:]
    frames = [(float(l.split(',')[1]), os.path.join(d, l.split(',')[2])) for l in lines if l]
    nav = np.loadtxt(os.path.join(d, 'navigation.tum'), comments='#', ndmin=2)
    return sensor, frames, nav


def quat_matrix(q):  # [x, y, z, w]
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def matrix_quat(R):
    w = math.sqrt(max(0.0, 1 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + R[0, 0] - R[1, 1] - R[2, 2])) / 2, R[2, 1] - R[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - R[0, 0] + R[1, 1] - R[2, 2])) / 2, R[0, 2] - R[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - R[0, 0] - R[1, 1] + R[2, 2])) / 2, R[1, 0] - R[0, 1])
    return np.array([x, y, z, w])


def rpy_matrix(roll, pitch, yaw):  # R = Rz(yaw)·Ry(pitch)·Rx(roll), radians
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return Rz @ Ry @ Rx


def iso(t, R):
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def mounting_of(sensor):
    m = sensor['T_vehicle_sonar']
    return iso(np.array(m['translation'], float), quat_matrix(m['quaternion']))


def tum_pose(row):
    return iso(row[1:4], quat_matrix(row[4:8]))


# p_msg = R·p_flu: ProjectedSonarImage's frame (z forward, x up) from our FLU sonar frame.
R_MSG_FLU = np.array([[0.0, 0, 1], [0, -1, 0], [1, 0, 0]])


def assert_rotation_close(tc, A, B, tol, what):
    err = np.linalg.norm(A - B)
    tc.assertLess(err, tol, f'{what}:\n{A}\n!=\n{B}')


SCENES = {
    # 16-bit frames, the identity mounting, 80 beams × 200 bins.
    'ds16': """
seed: 2
sensor: {preset: sim-10deg, beams: 80, fov_deg: 40}
simulation: {elevation_step_deg: 0.05}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.4}, pose: {translation: [2.5, 0, 0]}, reflectivity: 0.9}
trajectory: {period: 0.1, type: straight, start: [0, 0, -0.3], end: [0, 0, 0.3], spacing: 0.1}
""",
    # 8-bit frames, a rotated and offset mounting, a rolled, pitched and turned vehicle.
    'ds8': """
seed: 3
sensor:
  preset: sim-10deg
  beams: 64
  fov_deg: 40
  range_bins: 120
  intensity: {bit_depth: 8, scale: 0.00392156862745098}
  T_vehicle_sonar: {translation: [0.3, 0.1, -0.2], rpy_deg: [0, 10, 5]}
simulation: {elevation_step_deg: 0.05}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.4}, pose: {translation: [2.8, 0.6, -0.5]}, reflectivity: 0.9}
trajectory: {period: 0.1, type: straight, start: [0, 0, -0.3], end: [0, 0, 0.3], spacing: 0.1, rpy_deg: [3, -2, 8]}
""",
}


def setUpModule():
    global WORK
    WORK = tempfile.mkdtemp(prefix='sonar3d_test_rosbag_debian_')
    for name, scene in SCENES.items():
        path = os.path.join(WORK, name + '.yaml')
        with open(path, 'w') as f:
            f.write(scene)
        run('simulate', path, '-o', os.path.join(WORK, name), '--quiet')


def tearDownModule():
    shutil.rmtree(WORK, ignore_errors=True)


# ------------------------------------------------------------------------ sonar3d → rosbag

class ExportReadsInDebianRosbag(unittest.TestCase):
    def check_export(self, dataset, compression, package):
        ds = os.path.join(WORK, dataset)
        bag_path = os.path.join(WORK, f'{dataset}_{compression}_{package}.bag')
        run('export', 'rosbag', ds, '-o', bag_path, '--ros1', '--compression', compression,
            '--package', package, '--quiet')
        sensor, frames, nav = read_dataset(ds)
        beams, bins = sensor['beams'], sensor['range_bins']
        bits = sensor['intensity']['bit_depth']
        sonar_type = f'{package}/ProjectedSonarImage'

        # `rosbag info` (Debian's CLI) reads the bag's index and names what it holds.
        info = subprocess.run([ROSBAG_CLI, 'info', bag_path], capture_output=True, text=True)
        self.assertEqual(info.returncode, 0, info.stderr)
        self.assertIn('version:', info.stdout)
        self.assertIn(f'compression: {compression}', ' '.join(info.stdout.split()))
        self.assertIn(f'/sonar3d/image {len(frames)} msgs : {sonar_type}',
                      ' '.join(info.stdout.split()))

        with rosbag.Bag(bag_path) as bag:
            self.assertEqual(bag.get_compression_info().compression, compression)
            topics = bag.get_type_and_topic_info().topics
            self.assertEqual({t: (v.msg_type, v.message_count) for t, v in topics.items()},
                             {'/sonar3d/image': (sonar_type, len(frames)),
                              '/sonar3d/odom': ('nav_msgs/Odometry', len(nav)),
                              '/tf_static': ('tf2_msgs/TFMessage', 1)})
            self.assertAlmostEqual(bag.get_start_time(), frames[0][0], delta=1e-9)
            self.assertAlmostEqual(bag.get_end_time(), max(frames[-1][0], nav[-1, 0]),
                                   delta=1e-9)
            # Each connection's MD5 is the one genpy computes from the stored definition (what
            # rosbag checks before it decodes), and the installed packages' for theirs.
            installed = {'nav_msgs/Odometry': Odometry, 'tf2_msgs/TFMessage': TFMessage}
            for c in bag._connections.values():
                cls = genpy.dynamic.generate_dynamic(c.datatype, c.msg_def)[c.datatype]
                self.assertEqual(cls._md5sum, c.md5sum, c.datatype)
                if c.datatype in installed:
                    self.assertEqual(c.md5sum, installed[c.datatype]._md5sum, c.datatype)
                self.assertEqual(c.header.get('latching') == b'1', c.topic == '/tf_static')

            # The mounting: base_link -> sonar (the message frame, z forward, x up).
            tfs = [m for _, m, _ in bag.read_messages(topics=['/tf_static'])]
            self.assertEqual(len(tfs[0].transforms), 1)
            tr = tfs[0].transforms[0]
            self.assertEqual((tr.header.frame_id, tr.child_frame_id), ('base_link', 'sonar'))
            T = mounting_of(sensor)
            t, q = tr.transform.translation, tr.transform.rotation
            np.testing.assert_allclose([t.x, t.y, t.z], T[:3, 3], atol=1e-9)
            assert_rotation_close(self, quat_matrix([q.x, q.y, q.z, q.w]), T[:3, :3] @ R_MSG_FLU,
                                  1e-9, 'tf_static rotation')

            # Navigation: one Odometry per navigation.tum line, map -> base_link.
            odoms = list(bag.read_messages(topics=['/sonar3d/odom']))
            self.assertEqual(len(odoms), len(nav))
            for (_, m, t), row in zip(odoms, nav):
                self.assertEqual((m.header.frame_id, m.child_frame_id), ('map', 'base_link'))
                # the record time is the stamp, from 1 ns (rosbag play refuses 0)
                self.assertEqual(t, max(m.header.stamp, rospy.Time(0, 1)))
                self.assertAlmostEqual(m.header.stamp.to_sec(), row[0], delta=1e-9)
                p, o = m.pose.pose.position, m.pose.pose.orientation
                np.testing.assert_allclose([p.x, p.y, p.z], row[1:4], atol=1e-9)
                assert_rotation_close(self, quat_matrix([o.x, o.y, o.z, o.w]),
                                      quat_matrix(row[4:8]), 1e-9, 'odometry orientation')

            # Every image against its frame: stamps, geometry, dtype and the stored values.
            fov = math.radians(sensor['fov_deg'])
            bearings = [-fov / 2 + (j + 0.5) * fov / beams for j in range(beams)]
            dr = (sensor['r_max'] - sensor['r_min']) / bins
            ranges = [sensor['r_min'] + (i + 0.5) * dr for i in range(bins)]
            images = list(bag.read_messages(topics=['/sonar3d/image'],
                                            return_connection_header=True))
            self.assertEqual(len(images), len(frames))
            lit = 0
            for (_, m, t, conn), (stamp, png) in zip(images, frames):
                # (not m._type: rosbag caches decoded classes by MD5 sum, which both packages'
                # ProjectedSonarImage share, so a process that read the other one first reuses it)
                self.assertEqual(conn['type'].decode(), sonar_type)
                # the record time is the stamp, from 1 ns (rosbag play refuses 0)
                self.assertEqual(t, max(m.header.stamp, rospy.Time(0, 1)))
                self.assertAlmostEqual(m.header.stamp.to_sec(), stamp, delta=1e-9)
                self.assertEqual(m.header.frame_id, 'sonar')
                self.assertEqual(len(m.beam_directions), beams)
                for d, phi in zip(m.beam_directions, bearings):
                    self.assertAlmostEqual(math.atan2(-d.y, d.z), phi, delta=1e-6)
                    self.assertAlmostEqual(d.x, 0.0, delta=1e-9)
                np.testing.assert_allclose(m.ranges, ranges, atol=1e-6)
                self.assertAlmostEqual(m.ping_info.tx_beamwidths[0],
                                       math.radians(sensor['vertical_aperture_deg']), delta=1e-6)
                img = m.image
                self.assertEqual(img.dtype, 0 if bits == 8 else 2)  # DTYPE_UINT8 / DTYPE_UINT16
                self.assertEqual(img.beam_count, beams)
                self.assertFalse(img.is_bigendian)
                self.assertEqual(len(img.data), bins * beams * bits // 8)
                got = np.frombuffer(img.data, np.uint8 if bits == 8 else '<u2').reshape(bins, beams)
                want = read_png(png)
                np.testing.assert_array_equal(got, want)
                lit += int(np.count_nonzero(want))
            self.assertGreater(lit, 100, 'the simulated sphere should light up the frames')
        return bag_path

    def test_16bit_uncompressed(self):
        self.check_export('ds16', 'none', 'marine_acoustic_msgs')

    def test_16bit_lz4_acoustic_msgs(self):
        self.check_export('ds16', 'lz4', 'acoustic_msgs')

    def test_8bit_bz2_mounted(self):
        self.check_export('ds8', 'bz2', 'marine_acoustic_msgs')

    def test_rerecorded_by_rosbag_imports_to_the_same_dataset(self):
        # Debian's rosbag re-writes sonar3d's bag (messages decoded and re-serialized by genpy,
        # new topic names, small lz4 chunks); importing that gives back the dataset.
        src = self.check_export('ds8', 'none', 'marine_acoustic_msgs')
        again = os.path.join(WORK, 'rerecorded.bag')
        names = {'/sonar3d/image': '/oculus/sonar', '/sonar3d/odom': '/nav/odom',
                 '/tf_static': '/tf_static'}
        with rosbag.Bag(src) as inp, rosbag.Bag(again, 'w', compression='lz4',
                                                chunk_threshold=8192) as out:
            for topic, msg, t, conn in inp.read_messages(return_connection_header=True):
                out.write(names[topic], msg, t, connection_header=conn)
        out_ds = os.path.join(WORK, 'rerecorded_ds')
        run('import', 'rosbag', again, '--sonar-topic', '/oculus/sonar', '--nav-topic',
            '/nav/odom', '-o', out_ds, '--quiet')
        sensor, frames, nav = read_dataset(os.path.join(WORK, 'ds8'))
        got_sensor, got_frames, got_nav = read_dataset(out_ds)
        self.assertEqual(len(got_frames), len(frames))
        for (t0, a), (t1, b) in zip(frames, got_frames):
            self.assertAlmostEqual(t0, t1, delta=1e-9)
            np.testing.assert_array_equal(read_png(a), read_png(b))
        np.testing.assert_allclose(got_nav, nav, atol=1e-9)
        np.testing.assert_allclose(mounting_of(got_sensor), mounting_of(sensor), atol=1e-9)
        self.assertEqual(got_sensor['range_bins'], sensor['range_bins'])
        self.assertAlmostEqual(got_sensor['r_min'], sensor['r_min'], delta=1e-6)
        self.assertAlmostEqual(got_sensor['r_max'], sensor['r_max'], delta=1e-6)


# ------------------------------------------------------------------------ rosbag → sonar3d

BINS, BEAMS = 50, 32
T0 = 1700000000.25  # a real epoch: stamps keep their nanoseconds


def stamp(sec):
    return rospy.Time.from_sec(sec)


def vehicle_pose(k):
    """A vehicle moving north-east, turning and rolling slightly (sample k of 20 Hz)."""
    s = k * 0.05
    R = rpy_matrix(math.radians(2 * math.sin(s)), math.radians(-3 + s), math.radians(30 + 10 * s))
    return iso([1.0 + 0.4 * s, -2.0 + 0.3 * s, -5.0 - 0.05 * s], R)


def write_description(path, bits):
    scale = 1 / 255 if bits == 8 else 1 / 65535
    desc = {'format': 'sonar3d-dataset', 'version': 1,
            'sensor': {'name': 'debian-rosbag-test', 'fov_deg': 60, 'beams': BEAMS, 'r_min': 0.5,
                       'r_max': 10.5, 'range_bins': BINS, 'vertical_aperture_deg': 12,
                       'beam_pattern': {'type': 'sinc'},
                       'intensity': {'bit_depth': bits, 'scale': scale}}}
    with open(path, 'w') as f:
        yaml.safe_dump(desc, f)


def transform(parent, child, T, when):
    m = TransformStamped()
    m.header.stamp = when
    m.header.frame_id = parent
    m.child_frame_id = child
    m.transform.translation.x, m.transform.translation.y, m.transform.translation.z = T[:3, 3]
    q = matrix_quat(T[:3, :3])
    r = m.transform.rotation
    r.x, r.y, r.z, r.w = q
    return m


def latched(topic):
    # What `rosbag record` stores for a latched publisher (tf2_ros' static broadcaster).
    return {'callerid': '/static_transform_publisher_1', 'latching': '1', 'topic': topic,
            'type': 'tf2_msgs/TFMessage', 'md5sum': TFMessage._md5sum,
            'message_definition': TFMessage._full_text}


class RosbagWrittenBagsImport(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(dir=WORK)

    def frames(self, n, bits, seed):
        rng = np.random.default_rng(seed)
        top = 255 if bits == 8 else 65535
        return [rng.integers(0, top + 1, size=(BINS, BEAMS)).astype(
            np.uint8 if bits == 8 else np.uint16) for _ in range(n)]

    def image(self, a, encoding, when, frame_id):
        m = Image()
        m.header.stamp = when
        m.header.frame_id = frame_id
        m.height, m.width = a.shape
        m.encoding = encoding
        m.is_bigendian = 0
        m.step = a.shape[1] * a.itemsize
        m.data = a.astype(a.dtype.newbyteorder('<')).tobytes()
        return m

    def check_import(self, bag_path, args, images, stamps, nav, T_vehicle_sonar, mount_text):
        out = os.path.join(self.dir, 'ds')
        p = run('import', 'rosbag', bag_path, '-o', out, *args)
        self.assertIn(f'imported {len(images)} frames', p.stdout)
        self.assertIn(f'mounting: {mount_text}', p.stdout)
        sensor, frames, got_nav = read_dataset(out)
        self.assertEqual(len(frames), len(images))
        for (t, png), want, st in zip(frames, images, stamps):
            self.assertAlmostEqual(t, st, delta=1e-6)
            np.testing.assert_array_equal(read_png(png), want)
        self.assertEqual(len(got_nav), len(nav))
        for row, (t, T) in zip(got_nav, nav):
            self.assertAlmostEqual(row[0], t, delta=1e-6)
            np.testing.assert_allclose(row[1:4], T[:3, 3], atol=1e-9)
            assert_rotation_close(self, quat_matrix(row[4:8]), T[:3, :3], 1e-9, 'vehicle pose')
        np.testing.assert_allclose(mounting_of(sensor), T_vehicle_sonar, atol=1e-9)
        return out

    def test_image_odometry_and_two_static_broadcasters(self):
        # sensor_msgs/Image (mono16) + nav_msgs/Odometry; the mounting base_link -> mast -> sonar
        # from two latched /tf_static publishers (two connections on one topic), uncompressed.
        T_base_mast = iso([0.4, 0.0, 0.8], rpy_matrix(0, 0, math.radians(-4)))
        T_mast_sonar = iso([0.05, -0.1, -0.3], rpy_matrix(math.radians(1), math.radians(25), 0))
        images = self.frames(12, 16, seed=5)
        stamps = [T0 + 0.1 + 0.1 * k for k in range(len(images))]
        nav = [(T0 + 0.05 * k, vehicle_pose(k)) for k in range(30)]
        bag_path = os.path.join(self.dir, 'odometry.bag')
        with rosbag.Bag(bag_path, 'w') as bag:
            tf1 = TFMessage(transforms=[transform('base_link', 'mast', T_base_mast, stamp(T0))])
            tf2 = TFMessage(transforms=[transform('mast', 'sonar', T_mast_sonar, stamp(T0))])
            hdr2 = dict(latched('/tf_static'), callerid='/static_transform_publisher_2')
            bag.write('/tf_static', tf1, stamp(T0), connection_header=latched('/tf_static'))
            bag.write('/tf_static', tf2, stamp(T0), connection_header=hdr2)
            events = [(t, 'nav', k) for k, (t, _) in enumerate(nav)] + \
                     [(t, 'img', k) for k, t in enumerate(stamps)]
            for t, kind, k in sorted(events):
                received = stamp(t + 0.013)  # the recorder's clock, after the header stamp
                if kind == 'nav':
                    m = Odometry()
                    m.header.stamp = stamp(t)
                    m.header.frame_id = 'odom'
                    m.child_frame_id = 'base_link'
                    T = nav[k][1]
                    p, o = m.pose.pose.position, m.pose.pose.orientation
                    p.x, p.y, p.z = T[:3, 3]
                    o.x, o.y, o.z, o.w = matrix_quat(T[:3, :3])
                    bag.write('/odom', m, received)
                else:
                    bag.write('/sonar/image', self.image(images[k], 'mono16', stamp(t), 'sonar'),
                              received)
        desc = os.path.join(self.dir, 'sonar.yaml')
        write_description(desc, 16)
        self.check_import(bag_path, ['--sonar-topic', '/sonar/image', '--nav-topic', '/odom',
                                     '--sonar', desc, '--quiet'],
                          images, stamps, nav, T_base_mast @ T_mast_sonar,
                          '/tf_static: base_link -> mast -> sonar')

    def test_image_posestamped_bz2(self):
        # sensor_msgs/Image (mono8) + geometry_msgs/PoseStamped: no child frame, so the vehicle
        # frame is the root of the static tree above the sonar; bz2 chunks.
        T_base_sonar = iso([0.7, 0.2, -0.4], rpy_matrix(0, math.radians(30), math.radians(10)))
        images = self.frames(9, 8, seed=6)
        stamps = [T0 + 0.2 + 0.1 * k for k in range(len(images))]
        nav = [(T0 + 0.05 * k, vehicle_pose(k)) for k in range(25)]
        bag_path = os.path.join(self.dir, 'posestamped.bag')
        with rosbag.Bag(bag_path, 'w', compression='bz2') as bag:
            tf = TFMessage(transforms=[transform('base_link', 'sonar_link', T_base_sonar,
                                                 stamp(T0))])
            bag.write('/tf_static', tf, stamp(T0), connection_header=latched('/tf_static'))
            for t, T in nav:
                m = PoseStamped()
                m.header.stamp = stamp(t)
                m.header.frame_id = 'map'
                p, o = m.pose.position, m.pose.orientation
                p.x, p.y, p.z = T[:3, 3]
                o.x, o.y, o.z, o.w = matrix_quat(T[:3, :3])
                bag.write('/pose', m, stamp(t))
            for a, t in zip(images, stamps):
                bag.write('/sonar/image', self.image(a, 'mono8', stamp(t), 'sonar_link'), stamp(t))
        desc = os.path.join(self.dir, 'sonar.yaml')
        write_description(desc, 8)
        self.check_import(bag_path, ['--sonar-topic', '/sonar/image', '--nav-topic', '/pose',
                                     '--sonar', desc, '--quiet'],
                          images, stamps, nav, T_base_sonar,
                          '/tf_static: base_link -> sonar_link')

    def test_lz4_chunks_out_of_order_and_leading_slash_frames(self):
        # 16UC1 images in many small lz4 chunks, written topic after topic (the file is not in
        # time order), the static transform last; ROS 1 frame names with a leading slash in TF
        # and the Odometry but not in the images (tf2 treats '/base_link' as 'base_link').
        T_base_sonar = iso([0.1, 0.0, -0.6], rpy_matrix(0, math.radians(45), 0))
        images = self.frames(10, 16, seed=7)
        stamps = [T0 + 0.12 + 0.1 * k for k in range(len(images))]
        nav = [(T0 + 0.05 * k, vehicle_pose(k)) for k in range(24)]
        bag_path = os.path.join(self.dir, 'lz4.bag')
        with rosbag.Bag(bag_path, 'w', compression='lz4', chunk_threshold=4096) as bag:
            for a, t in zip(reversed(images), reversed(stamps)):
                bag.write('/sonar/image', self.image(a, '16UC1', stamp(t), 'sonar'), stamp(t))
            for t, T in nav:
                m = Odometry()
                m.header.stamp = stamp(t)
                m.header.frame_id = '/odom'
                m.child_frame_id = '/base_link'
                p, o = m.pose.pose.position, m.pose.pose.orientation
                p.x, p.y, p.z = T[:3, 3]
                o.x, o.y, o.z, o.w = matrix_quat(T[:3, :3])
                bag.write('/odom', m, stamp(t))
            tf = TFMessage(transforms=[transform('/base_link', '/sonar', T_base_sonar, stamp(T0))])
            bag.write('/tf_static', tf, stamp(T0), connection_header=latched('/tf_static'))
        with rosbag.Bag(bag_path) as bag:
            self.assertEqual(bag.get_compression_info().compression, 'lz4')
            self.assertGreater(len(bag._chunks), 3)
        desc = os.path.join(self.dir, 'sonar.yaml')
        write_description(desc, 16)
        self.check_import(bag_path, ['--sonar-topic', '/sonar/image', '--nav-topic', '/odom',
                                     '--sonar', desc, '--quiet'],
                          images, stamps, nav, T_base_sonar, '/tf_static: base_link -> sonar')

    def test_float_images_import_and_export_back_to_rosbag(self):
        # sensor_msgs/Image 32FC1 (linear intensities) + Odometry, mounting given by --mount:
        # the dataset keeps float TIFF frames; exported again as a ROS 1 bag, Debian's rosbag
        # reads DTYPE_FLOAT32 images holding the very floats that were recorded.
        rng = np.random.default_rng(8)
        images = [rng.random((BINS, BEAMS), dtype=np.float32) * 3 for _ in range(6)]
        stamps = [T0 + 0.1 + 0.1 * k for k in range(len(images))]
        nav = [(T0 + 0.05 * k, vehicle_pose(k)) for k in range(16)]
        bag_path = os.path.join(self.dir, 'float.bag')
        with rosbag.Bag(bag_path, 'w', compression='bz2') as bag:
            for t, T in nav:
                m = Odometry()
                m.header.stamp = stamp(t)
                m.header.frame_id = 'odom'
                m.child_frame_id = 'base_link'
                p, o = m.pose.pose.position, m.pose.pose.orientation
                p.x, p.y, p.z = T[:3, 3]
                o.x, o.y, o.z, o.w = matrix_quat(T[:3, :3])
                bag.write('/odom', m, stamp(t))
            for a, t in zip(images, stamps):
                bag.write('/sonar/image', self.image(a, '32FC1', stamp(t), 'sonar'), stamp(t))
        desc = os.path.join(self.dir, 'sonar.yaml')
        write_description(desc, 16)
        out = os.path.join(self.dir, 'ds')
        p = run('import', 'rosbag', bag_path, '-o', out, '--sonar-topic', '/sonar/image',
                '--nav-topic', '/odom', '--sonar', desc, '--mount', '0.2,0,-0.5,0,20,0', '--quiet')
        self.assertIn(f'imported {len(images)} frames', p.stdout)
        sensor, frames, got_nav = read_dataset(out)
        self.assertTrue(all(f.endswith('.tiff') for _, f in frames), frames)
        T_mount = iso([0.2, 0, -0.5], rpy_matrix(0, math.radians(20), 0))
        np.testing.assert_allclose(mounting_of(sensor), T_mount, atol=1e-9)
        np.testing.assert_allclose(got_nav[:, 0], [t for t, _ in nav], atol=1e-6)

        back = os.path.join(self.dir, 'back.bag')
        run('export', 'rosbag', out, '-o', back, '--ros1', '--compression', 'lz4', '--quiet')
        with rosbag.Bag(back) as bag:
            got = list(bag.read_messages(topics=['/sonar3d/image']))
            self.assertEqual(len(got), len(images))
            for (_, m, _), a, t in zip(got, images, stamps):
                self.assertAlmostEqual(m.header.stamp.to_sec(), t, delta=1e-6)
                self.assertEqual(m.image.dtype, 8)  # DTYPE_FLOAT32
                self.assertEqual(m.image.beam_count, BEAMS)
                np.testing.assert_array_equal(
                    np.frombuffer(m.image.data, '<f4').reshape(BINS, BEAMS), a)
            (_, tf, _), = bag.read_messages(topics=['/tf_static'])
            q = tf.transforms[0].transform.rotation
            assert_rotation_close(self, quat_matrix([q.x, q.y, q.z, q.w]),
                                  T_mount[:3, :3] @ R_MSG_FLU, 1e-9, 'exported mounting')

    def test_bad_image_is_one_clear_line_and_nothing_written(self):
        a = np.zeros((BINS, BEAMS * 3), np.uint8)
        bag_path = os.path.join(self.dir, 'rgb.bag')
        with rosbag.Bag(bag_path, 'w') as bag:
            m = self.image(a, 'rgb8', stamp(T0), 'sonar')
            m.width, m.step = BEAMS, BEAMS * 3
            bag.write('/sonar/image', m, stamp(T0))
        desc = os.path.join(self.dir, 'sonar.yaml')
        write_description(desc, 8)
        out = os.path.join(self.dir, 'ds')
        p = run('import', 'rosbag', bag_path, '-o', out, '--sonar-topic', '/sonar/image',
                '--static', '--sonar', desc, '--quiet', ok=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
        self.assertIn("encoding 'rgb8'", p.stderr)
        self.assertIn('rgb.bag', p.stderr)
        self.assertFalse(os.path.exists(out))


if __name__ == '__main__':
    if len(sys.argv) < 2:
        sys.exit('usage: test_rosbag_debian.py SONAR3D_CLI [unittest args]')
    CLI = os.path.abspath(sys.argv.pop(1))
    unittest.main(verbosity=2)
