#!/usr/bin/env python3
# Regenerates the seed corpora in fuzz/corpus/ (run from the repository root with Debian python3 + numpy).
import os, struct, zlib, pickle, json
R='fuzz/corpus'
def w(t, name, data):
    os.makedirs(f'{R}/{t}', exist_ok=True)
    if isinstance(data, str): data = data.encode()
    open(f'{R}/{t}/{name}', 'wb').write(data)
SEP = '\n--8<--\n'
def png16(w_, h, val=1000, bits=16):
    def chunk(t, d): return struct.pack('>I', len(d)) + t + d + struct.pack('>I', zlib.crc32(t + d) & 0xffffffff)
    if bits == 16: row = b'\0' + struct.pack('>H', val) * w_
    else: row = b'\0' + bytes([val & 255]) * w_
    raw = row * h
    return b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', w_, h, bits, 0, 0, 0, 0)) + chunk(b'IDAT', zlib.compress(raw)) + chunk(b'IEND', b'')
sonar = """format: sonar3d-dataset
version: 1
sensor:
  name: small
  fov_deg: 20
  beams: 4
  r_min: 0.5
  r_max: 2.5
  range_bins: 8
  vertical_aperture_deg: 10
  beam_pattern: {type: sinc}
  intensity: {bit_depth: 16, scale: 1.5259021896696422e-05}
  T_vehicle_sonar: {translation: [0.1, 0, 0], quaternion: [0, 0, 0, 1]}
"""
frames = "index,timestamp,file\n0,10,frames/000000.png\n"
nav = "# t tx ty tz qx qy qz qw\n9 0 0 0 0 0 0 1\n11 1 0 0 0 0 0 1\n"
w('dataset', 'png16', sonar + SEP + frames + SEP + nav + SEP)
open(f'{R}/dataset/png16', 'ab').write(png16(4, 8))
w('dataset', 'tiff_rpy', sonar.replace('quaternion: [0, 0, 0, 1]', 'rpy_deg: [0, 10, 0]').replace('beam_pattern: {type: sinc}', 'beam_pattern: {type: table, elevation_deg: [-5, 0, 5], amplitude: [0.5, 1, 0.5]}') + SEP + frames.replace('.png', '.tiff') + '1,10.5,frames/000000.png\n' + SEP + nav + SEP)
open(f'{R}/dataset/tiff_rpy', 'ab').write(png16(4, 8))
w('dataset', 'png8_bearings', sonar.replace('fov_deg: 20\n  beams: 4', 'bearings_deg: [-10, -4, 3, 10]').replace('bit_depth: 16', 'bit_depth: 8').replace('scale: 1.5259021896696422e-05', 'scale: 0.00392156862745098') + SEP + frames + SEP + nav + SEP)
open(f'{R}/dataset/png8_bearings', 'ab').write(png16(4, 8, 200, 8))

scene = """seed: 1
sensor:
  preset: sim-10deg
  fov_deg: 30
  beams: 16
  range_bins: 20
simulation: {elevation_step_deg: 1, rays_per_beam: 1, jitter: true, gain: 2.0, num_threads: 1}
objects:
  - {name: ball, primitive: {type: sphere, radius: 0.5}, pose: {translation: [0, 0, 0]}, reflectivity: 0.8}
  - {name: box, primitive: {type: box, size: [0.2, 0.3, 0.4]}, pose: {translation: [0, 1, 0], rpy_deg: [0, 0, 30]}}
trajectory:
  period: 0.1
  segments:
    - {type: straight, start: [-3, 0, -0.3], end: [-3, 0, 0.3], spacing: 0.1}
    - {type: orbit, center: [0, 0, 0], radius: 3, count: 4, start_deg: 0, sweep_deg: 90}
"""
w('scene', 'segments', scene)
w('scene', 'lawnmower_stripes', scene.replace("""  segments:
    - {type: straight, start: [-3, 0, -0.3], end: [-3, 0, 0.3], spacing: 0.1}
    - {type: orbit, center: [0, 0, 0], radius: 3, count: 4, start_deg: 0, sweep_deg: 90}
""", """  type: lawnmower
  x: [-1, 1]
  y: [-1, 0]
  z: 2
  line_spacing: 0.5
  spacing: 0.5
noise:
  model: stripes
  scale: 1
  stripes: {count: 3, width_deg: 2}
"""))
w('scene', 'tum_cylinder', """sensor: {preset: sim-1deg, range_bins: 10, fov_deg: 10, beams: 8}
objects:
  - {name: c, primitive: {type: cylinder, radius: 0.2, height: 1}, scale: 2}
  - {name: p, primitive: {type: plane, size: [2, 2]}, pose: {translation: [0, 0, -1], quaternion: [0, 0, 0, 1]}}
trajectory: {type: tum, file: traj.tum}
""" + SEP + "0 -3 0 0 0 0 0 1\n0.1 -3 0 0.1 0 0 0 1\n")

w('scene', 'field_pipeline_turns', """seed: 2
navigation_error: {velocity_scale: 0.01, bias_walk: 0.00005, heading_bias_deg: 0.2, depth_offset: 0.05}
sensor: {preset: mb2250, r_min: 1, r_max: 4, range_bins: 20, beams: 16, T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}
objects:
  - {name: seabed, primitive: {type: terrain, size: [4, 3], cell: 0.2, relief: 0.1, rocks: 2, trenches: 1}}
  - {name: pipe, pipeline: {from: [-1, -1, 0], to: [1, 1, 0], radius: 0.1, burial: 0.5}, reflectivity: 0.7}
  - {name: slab, primitive: {type: box, size: [0.5, 0.5, 0.1]}, kind: terrain}
trajectory: {type: lawnmower, x: [-1, 1], y: [-1, 1], z: 3, line_spacing: 1, spacing: 0.2, heading_deg: 30, turn_radius: 0.5}
""")

w('colmap', 'two_cameras', '# c\n1 OPENCV 640 480 500 505 320.5 240.5 -0.1 0.01 0.001 -0.001\n2 SIMPLE_RADIAL 100 80 90 50.5 40.5 0.01' + SEP + '# i\n1 0.7071 0 0.7071 0 1 2 3 1 a b.png\n10.5 3 -1 4 5 6\n2 1 0 0 0 0 0 0 2 c.jpg\n\n')
w('colmap', 'full_opencv', '1 FULL_OPENCV 1280 960 900 905 641.8 479.4 -0.12 0.03 0.0008 -0.0005 -0.002 0 0 0' + SEP + '5 0.5 -0.5 0.5 -0.5 2 3 -1 1 frame.png\n\n')

cam = 'format: sonar3d-camera\nversion: 1\nwidth: 320\nheight: 240\nfx: 200\nfy: 201\ncx: 159.5\ncy: 119.5\nk1: -0.05\nk2: 0.01\np1: 0\np2: 0\nk3: 0\nT_vehicle_camera:\n  translation: [0.1, 0, -0.2]\n  quaternion: [1, 0, 0, 0]\n'
cam_frames = 'index,timestamp,file\n0,10,camera/frames/000000.png\n1,10.5,camera/frames/000001.png\n'
w('camera_dataset', 'simulated', cam + SEP + cam_frames + SEP + nav)
w('camera_dataset', 'rpy_pinhole', cam.replace('quaternion: [1, 0, 0, 0]', 'rpy_deg: [180, 0, 90]').replace('k1: -0.05\n', '') + SEP + cam_frames.replace('10.5', '11') + SEP + nav)

for f in os.listdir('data/sweeps'):
    w('sweep', f.replace('.yaml', ''), open('data/sweeps/' + f).read())

ply_ascii = "ply\nformat ascii 1.0\ncomment x\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float intensity\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 1\n1 0 0 0.5\n0 1 0 0.25\n3 0 1 2\n"
w('ply', 'ascii_face', ply_ascii)
hdr = "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty float intensity\nend_header\n"
w('ply', 'binary', hdr.encode() + struct.pack('<8f', 1, 2, 3, 0.5, 4, 5, 6, 0.25))
hdr2 = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
w('ply', 'binary_double_face', hdr2.encode() + b''.join(struct.pack('<dddB', *v, 7) for v in [(0,0,0),(1,0,0),(0,1,0)]) + struct.pack('<B3i', 3, 0, 1, 2))

tri_ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n4 0 1 3 2\n"
w('mesh', 'ply_ascii', b'\x00' + tri_ply.encode())
w('mesh', 'ply_binary', b'\x06' + b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n" + struct.pack('<9f', 0,0,0, 1,0,0, 0,1,0) + struct.pack('<B3i', 3, 0, 1, 2))
w('mesh', 'obj', b'\x01' + b"o t\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\nf 1 2 3\nf 1//1 2//1 4//1\n")
w('mesh', 'stl', b'\x02' + b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n")
w('mesh', 'stl_binary', b'\x08' + b'\0' * 80 + struct.pack('<I', 1) + struct.pack('<12fH', 0,0,1, 0,0,0, 1,0,0, 0,1,0, 0))
w('mesh', 'off', b'\x03' + b"OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n")
dae = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries><geometry id="g"><mesh>
    <source id="p"><float_array id="pa" count="9">0 0 0 1 0 0 0 1 0</float_array>
      <technique_common><accessor source="#pa" count="3" stride="3"><param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
    <triangles count="1"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s"><node id="n"><matrix>1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1</matrix><instance_geometry url="#g"/></node></visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""
w('mesh', 'dae', b'\x04' + dae.encode())
import base64
buf = struct.pack('<9f', 0,0,0, 1,0,0, 0,1,0) + struct.pack('<3H', 0, 1, 2) + b'\0\0'
gltf = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "buffers": [{"uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode(), "byteLength": len(buf)}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]},
                {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]}
w('mesh', 'gltf', b'\x05' + json.dumps(gltf).encode())

cfg = {"name": "x", "agents": [{"agent_name": "auv0", "sensors": [
  {"sensor_type": "PoseSensor", "socket": "SonarSocket", "rotation": [0, 45, 0]},
  {"sensor_type": "ImagingSonar", "sensor_name": "Sonar", "socket": "SonarSocket", "Hz": 10, "rotation": [0, 45, 0],
   "configuration": {"RangeBins": 100, "AzimuthBins": 64, "RangeMin": 0.5, "RangeMax": 4.5, "Azimuth": 60, "Elevation": 12}}]}]}
w('holoocean_config', 'basic', json.dumps(cfg, indent=1))
cfg2 = json.loads(json.dumps(cfg)); cfg2["agents"].append({"agent_name": "b", "sensors": [{"sensor_type": "ImagingSonar", "configuration": {"RangeBins": 8, "AzimuthBins": 6, "RangeMin": 0.01, "RangeMax": 1e3, "Azimuth": 130, "Elevation": 1.5}}]})
w('holoocean_config', 'two_agents', json.dumps(cfg2))

import numpy as np
pose = np.eye(4, dtype=np.float32); pose[0, 3] = 1.5
w('pickle', 'float32', pickle.dumps({"ImagingSonar": np.linspace(0, 1, 48, dtype=np.float32).reshape(8, 6), "PoseSensor": pose}, protocol=2))
w('pickle', 'uint8_p4', pickle.dumps({"ImagingSonar": np.arange(48, dtype=np.uint8).reshape(8, 6), "PoseSensor": pose}, protocol=4))
w('pickle', 'wrong_shape', pickle.dumps({"ImagingSonar": np.zeros((3, 6), np.float32), "PoseSensor": pose.astype(np.float64)}, protocol=2))

w('navcsv', 'enu_deg', b'\x00' + b"time,x,y,z,roll,pitch,yaw\n# c\n0,0,0,-1,0,0,90\n0.5,1,0,-1,1,2,91\n1.0,2,0,-1,0,0,92\n")
w('navcsv', 'ned_rad_extra', b'\x03' + b"t, north, east, depth, roll, pitch, yaw, speed\n0,0,0,1,0,0,1.57,1\n1,1,1,1,0.01,0,1.6,1\n")
w('navcsv', 'tum', b'\x04' + b"# t tx ty tz qx qy qz qw\n0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0.7071068 0.7071068\n")

# Position fixes (fuzz_fixes): first byte bit 0 = TUM (else CSV), bit 1 = a σ for TUM fixes.
w('fixes', 'csv', b'\x00' + b"# USBL\ntime_s,x_m,y_m,sigma_m\n10,1.5,-2,1\n20,2.5,-2.1,1.5\n")
w('fixes', 'csv_z_any_order', b'\x00' + b"sigma_m, q, time_s, z_m, y_m, x_m\n0.5,3,1,-10,2,1\n0.5,3,2,-10,2,1.4\n")
w('fixes', 'tum', b'\x03' + b"# t x y z qx qy qz qw\n0 0 0 -5 0 0 0 1\n10 4 0 -5 0 0 0 1\n")
w('fixes', 'tum_no_sigma', b'\x01' + b"0 0 0 -5 0 0 0 1\n")
w('fixes', 'unsorted', b'\x00' + b"time_s,x_m,y_m,sigma_m\n2,0,0,1\n1,0,0,1\n")

# ARIS recordings (fuzz_aris): first byte = options, then the file (published ARIS layout:
# 1024-byte file header, frames of a 1024-byte header + samples × beams bytes).
def aris(frames=2, samples=4, ping=1, nav=True, cut=0):
    beams = {1: 48, 3: 96, 6: 64, 9: 128}[ping]
    fh = bytearray(1024)
    struct.pack_into('<II', fh, 0, 0x05464444, frames)
    struct.pack_into('<I', fh, 16, beams)
    struct.pack_into('<I', fh, 24, samples)
    out = bytes(fh)
    for k in range(frames):
        h = bytearray(1024)
        struct.pack_into('<IQI', h, 0, k, 1700000000000000 + 100000 * k, 0x05464444)
        struct.pack_into('<Q', h, 20, 1700000000000000 + 100000 * k + 7)
        if nav:
            struct.pack_into('<f', h, 128, 2.5)
            struct.pack_into('<fffff', h, 136, 1.0, 0, -2.0, 0, 45.0 + k)
            struct.pack_into('<dd', h, 172, 47.6 + 1e-6 * k, -122.3)
        struct.pack_into('<I', h, 436, ping)
        struct.pack_into('<I', h, 452, 20)
        struct.pack_into('<f', h, 464, 1500.0)
        struct.pack_into('<I', h, 468, samples)
        struct.pack_into('<I', h, 476, 1600)
        struct.pack_into('<I', h, 484, 1 if ping in (6, 9) else 0)
        struct.pack_into('<I', h, 516, 1)
        out += bytes(h) + bytes((i * 7 + k) % 256 for i in range(samples * beams))
    return out[:len(out) - cut] if cut else out
w('aris', 'header_nav', b'\x01' + aris())
w('aris', 'static_96', b'\x00' + aris(frames=3, samples=2, ping=3, nav=False))
w('aris', 'aris3000_64_cut', b'\x02' + aris(frames=3, samples=3, ping=6, cut=100))
w('aris', 'aris3000_128_sonar_clock', b'\x05' + aris(frames=1, samples=2, ping=9))

# Oculus ping streams (fuzz_oculus): first byte = options, then SimplePingResult messages (the
# published Oculus.h layout: v1 122-byte / v2 202-byte structures, int16 bearings in 0.01°, the
# image at imageOffset, a 4-byte gain before each line with fire flag bit 2), plus the first real
# ping of data/oculus (BSD-3, licence beside it) cut to its first 64 range lines.
def oculus(version=2, bytes_=2, gains=True, ranges=6, beams=4, k=0, msg_id=0x23):
    head = 202 if version == 2 else 122
    off = head + 2 * beams + 2
    line = beams * bytes_ + (4 if gains else 0)
    b = bytearray(off + line * ranges)
    struct.pack_into('<HHHHHIH', b, 0, 0x4f53, 1, 0, msg_id, version, len(b) - 16, 0)
    struct.pack_into('<BBBBBdddd', b, 16, 2, 0, 0, 0, 0x09 | (2 if bytes_ == 2 else 0) | (4 if gains else 0),
                     0.1 * ranges, 50.0, 0.0, 0.0)
    if version == 2:
        struct.pack_into('<IIdddddddd', b, 89, 10 + k, 0, 2.1e6, 10, 1, 0, 0, 0, 1480, 5.0 + 0.1 * k)
        struct.pack_into('<BdHH', b, 161, bytes_ - 1, 0.02, ranges, beams)
        struct.pack_into('<III', b, 190, off, line * ranges, len(b))
    else:
        struct.pack_into('<IIddddI', b, 53, 10 + k, 0, 1.2e6, 10, 1, 1480, 1000000 + 50000000 * k)
        struct.pack_into('<BdHHIII', b, 97, bytes_ - 1, 0.02, ranges, beams, off, line * ranges, len(b))
    for j in range(beams):
        struct.pack_into('<h', b, head + 2 * j, -3000 + j * 6000 // max(beams - 1, 1))
    for r in range(ranges):
        at = off + r * line
        if gains:
            struct.pack_into('<f', b, at, 1.5 + r)
            at += 4
        for j in range(beams):
            v = (37 * r + 11 * j + k) % (256 if bytes_ == 1 else 65536)
            struct.pack_into('<B' if bytes_ == 1 else '<H', b, at + bytes_ * j, v)
    return bytes(b)
w('oculus', 'v2_16bit_gains', b'\x00' + oculus() + oculus(k=1))
w('oculus', 'v2_16bit_gains_divide_mirror', b'\x03' + oculus(k=0) + oculus(k=1)[:-7])
w('oculus', 'v1_8bit_other_message', b'\x04' + oculus(1, 1, False) +
  struct.pack('<HHHHHIH', 0x4f53, 1, 0, 0x80, 0, 4, 0) + b'abcd' + oculus(1, 1, False, k=1))
real = open('data/oculus/three_pings_8bit.raw', 'rb').read()[:182016]
r = bytearray(real[:2048 + 64 * 256])
struct.pack_into('<I', r, 10, len(r) - 16)
struct.pack_into('<H', r, 106, 64)
struct.pack_into('<II', r, 114, 64 * 256, len(r))
w('oculus', 'real_ping_64_lines', b'\x00' + bytes(r))

# ROS bags (fuzz_rosbag) and messages (fuzz_rosmsg): a 2-frame dataset (4 beams × 8 range bins)
# exported by `sonar3d export rosbag` (ROS 2 and --ros1), so the seeds are what the importer
# reads; needs a built CLI ($SONAR3D, else build/bin/sonar3d). fuzz_rosmsg's seeds are the
# messages of the ROS 2 bag (CDR) and a hand-built ROS 1 PoseStamped.
import shutil, sqlite3, subprocess, tempfile
cli = os.environ.get('SONAR3D', 'build/bin/sonar3d')
if os.path.exists(cli):
    tmp = tempfile.mkdtemp()
    ds = f'{tmp}/ds'
    os.makedirs(f'{ds}/frames')
    open(f'{ds}/sonar.yaml', 'w').write(sonar)
    open(f'{ds}/frames.csv', 'w').write("index,timestamp,file\n0,10,frames/000000.png\n1,10.5,frames/000001.png\n")
    open(f'{ds}/navigation.tum', 'w').write(nav)
    for k in range(2):
        open(f'{ds}/frames/{k:06d}.png', 'wb').write(png16(4, 8, 1000 + 500 * k))
    subprocess.run([cli, 'export', 'rosbag', ds, '-o', f'{tmp}/b2', '-q'], check=True)
    subprocess.run([cli, 'export', 'rosbag', '--ros1', ds, '-o', f'{tmp}/b1.bag', '-q'], check=True)
    for c in ('bz2', 'lz4'):
        subprocess.run([cli, 'export', 'rosbag', '--ros1', '--compression', c, ds, '-o', f'{tmp}/{c}.bag', '-q'], check=True)
        w('rosbag', f'ros1_{c}', b'\x01' + open(f'{tmp}/{c}.bag', 'rb').read())
    db = open(f'{tmp}/b2/b2_0.db3', 'rb').read()
    b1 = open(f'{tmp}/b1.bag', 'rb').read()
    w('rosbag', 'ros2_nav', b'\x00' + db)
    w('rosbag', 'ros2_static', b'\x02' + db)
    w('rosbag', 'ros1_nav', b'\x01' + b1)
    w('rosbag', 'ros1_static_drop', b'\x07' + b1)
    con = sqlite3.connect(f'{tmp}/b2/b2_0.db3')
    sel = {'/sonar3d/image': 0, '/sonar3d/odom': 2 << 1, '/tf_static': 5 << 1}
    for name, tid in con.execute('SELECT name, id FROM topics'):
        blob = con.execute('SELECT data FROM messages WHERE topic_id=? LIMIT 1', (tid,)).fetchone()[0]
        w('rosmsg', 'cdr' + name.replace('/', '_'), bytes([sel[name]]) + blob)
    con.close()
    shutil.rmtree(tmp)
    pose1 = struct.pack('<III', 1, 10, 0) + struct.pack('<I', 3) + b'map' + struct.pack('<7d', 1, 2, 3, 0, 0, 0, 1)
    w('rosmsg', 'ros1_pose_stamped', bytes([1 | (3 << 1)]) + pose1)
else:
    print(f'make_corpus: {cli} not built: rosbag and rosmsg seeds left as they are')
# Recognition catalogues (fuzz_catalogue).
w('catalogue', 'field', "models:\n  - {name: riser, reference: riser, symmetry: none}\n  - {name: tank, reference: tank, symmetry: full, expected: 1}\n  - {name: pillar, reference: pillar, symmetry: \"180\", scale: 1.1}\n")
w('catalogue', 'block', "models:\n  - name: panel\n    mesh: meshes/bop_panel.dae\n    symmetry: \"180\"\n    expected: 2\n  - name: sphere\n    reference: sphere\n    symmetry: full\n    scale: 0.5\n")
w('catalogue', 'empty', "models: []\n")
# Scene-page JSON of `sonar3d report` (fuzz_report_scene): first byte even graph.json, odd
# changes.json (placements.json: fuzz_placements, the one reader).
I16 = '[1,0,0,2, 0,1,0,3, 0,0,1,0, 0,0,0,1]'
w('report_scene', 'world', b'\x00' + ('{"format":"sonar3d-world","version":1,"objects":[{"id":"tank_0","model":"tank","kind":"structure","T_world_model":' + I16 + ',"score_m":0.02,"residual_median_m":null,"file":"models/tank_0.ply"},{"id":"riser_0","model":"riser","kind":"structure","T_world_model":' + I16 + ',"score_m":0.03,"residual_median_m":0.01,"file":"models/riser_0.ply"}],"connections":[{"from":"tank_0","to":"riser_0","kind":"pipeline","length_m":4.5}],"seabed":[{"lod":0,"file":"seabed_lod0.ply","cell_m":0.1,"triangles":800,"bytes":12000,"median_error_m":0.01},{"lod":1,"file":"seabed_lod1.ply","cell_m":0.4,"triangles":50,"bytes":900,"median_error_m":null}],"source":{"map":"m","placements":"p.json","catalogue":"c.yaml"},"bytes_total":20000,"cloud_bytes":6000000}').encode())
w('report_scene', 'changes', b'\x01' + ('{"format":"sonar3d-changes","version":1,"T_a_b":' + I16 + ',"registration":{"method":"elevation","rms_m":0.01,"overlap_cells":1200},"objects":[{"id":"tank_0","model":"tank","status":"moved","T_world_model_a":' + I16 + ',"T_world_model_b_in_a":' + I16 + ',"shift_m":0.3,"turn_deg":10},{"id":"s","model":"sphere","status":"added","T_world_model_a":null,"T_world_model_b_in_a":' + I16 + ',"shift_m":null,"turn_deg":null}],"regions":[{"id":1,"centroid":[1,2,0],"area_m2":0.5,"max_abs_change_m":0.3,"mean_change_m":0.2,"kind":"raised"}],"thresholds":{"shift_m":0.05},"seconds":1.2}').encode())
w('report_scene', 'changes_colour', b'\x01' + ('{"format":"sonar3d-changes","version":1,"T_a_b":' + I16 + ',"registration":{"method":"elevation","rms_m":0.01,"overlap_cells":1200},"objects":[{"id":"tank_0","model":"tank","status":"moved","T_world_model_a":' + I16 + ',"T_world_model_b_in_a":' + I16 + ',"shift_m":0.3,"turn_deg":10},{"id":"s","model":"sphere","status":"added","T_world_model_a":null,"T_world_model_b_in_a":' + I16 + ',"shift_m":null,"turn_deg":null}],"regions":[{"id":1,"centroid":[1,2,0],"area_m2":0.5,"max_abs_change_m":0.3,"mean_change_m":0.2,"kind":"raised"}],"thresholds":{"shift_m":0.05},"colour":{"space":"chromaticity","cell_m":0.1,"offset":[0.5,-0.2],"sigma":1.0,"k_sigma":5,"threshold":5,"min_area_m2":0.05,"compared_cells":900,"significant_cells":40,"regions":[{"id":0,"centroid":[1,2,0.3],"area_m2":0.4,"cells":40,"max_delta":30,"mean_delta":25,"height_change_fraction":0,"colour_a":[220,80,70],"colour_b":[150,110,60]}]},"seconds":1.2}').encode())

# Placements of sonar3d recognize (fuzz_placements).
I4 = "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]"
w('placements', 'two', '{"format": "sonar3d-placements", "version": 1, "placements": [\n'
  ' {"model": "riser", "T_world_model": [[0.94, -0.34, 0, -12], [0.34, 0.94, 0, 6], [0, 0, 1, -0.1], [0, 0, 0, 1]]},\n'
  ' {"model": "tank", "T_world_model": ' + I4 + '}]}\n')
w('placements', 'flat16', '{"format": "sonar3d-placements", "version": 1, "placements": [{"model": "t", "T_world_model": [1,0,0,1, 0,1,0,2, 0,0,1,3, 0,0,0,1]}]}\n')
w('placements', 'method_mean', '{"format":"sonar3d-placements","version":1,"map":"m","catalogue":"c.yaml","placements":[{"model":"tank","method":"2d","T_world_model":[[1,0,0,2],[0,1,0,3],[0,0,1,0],[0,0,0,1]],"score_m":0.01,"residual_median_m":0.012,"residual_mean_m":null}]}')
w('connections', 'two', "connections:\n  - {from: box_0, to: box_1}\n  - {from: box_1, to: box_0, kind: cable}\n")
w('connections', 'block', "connections:\n  - from: box_0\n    to: box_1\n    kind: pipeline\n")
w('connections', 'unknown', "connections:\n  - {from: box_0, to: tank_3}\n")
w('placements', 'empty', '{"format": "sonar3d-placements", "version": 1, "placements": []}\n')
