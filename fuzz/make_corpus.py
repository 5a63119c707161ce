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

# Recognition catalogues (fuzz_catalogue).
w('catalogue', 'field', "models:\n  - {name: riser, reference: riser, symmetry: none}\n  - {name: tank, reference: tank, symmetry: full, expected: 1}\n  - {name: pillar, reference: pillar, symmetry: \"180\", scale: 1.1}\n")
w('catalogue', 'block', "models:\n  - name: panel\n    mesh: meshes/bop_panel.dae\n    symmetry: \"180\"\n    expected: 2\n  - name: sphere\n    reference: sphere\n    symmetry: full\n    scale: 0.5\n")
w('catalogue', 'empty', "models: []\n")
