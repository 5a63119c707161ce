#!/usr/bin/python3
"""The labelling of bench/recognition_fields.py on hand-made cases: which candidates are true, that
every numeric key (also nested and new ones) becomes a column, that accepted searches and 3D
summaries are not counted twice, and the cloud crop. Needs numpy only (python3-numpy)."""
import csv
import importlib.util
import json
import os
import sys
import tempfile
import unittest

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
spec = importlib.util.spec_from_file_location(
    'recognition_fields', os.path.join(HERE, '..', 'bench', 'recognition_fields.py'))
rf = importlib.util.module_from_spec(spec)
spec.loader.exec_module(rf)


def pose(x, y, yaw):
    return {'translation': [x, y, 0.0], 'rpy_deg': [0.0, 0.0, yaw]}


class Label(unittest.TestCase):
    def setUp(self):
        self.work = tempfile.mkdtemp()
        os.makedirs(os.path.join(self.work, 'runs'))
        # Model "a": bounding-box centre 0.5 m along its x axis, radius 2 m (tolerance 0.5 m).
        fields = {
            'models': {'a': {'center_xy': [0.5, 0.0], 'radius_m': 2.0},
                       'b': {'center_xy': [0.0, 0.0], 'radius_m': 0.4}},
            'fields': [{
                'name': 'f', 'symmetry': {'a': '180', 'b': 'none'},
                'structures': [dict(name='a', model='a', **pose(1, 2, 0)),
                               dict(name='a@2', model='a', **pose(5, 5, 90))],
                'clutter': [{'name': 'clutter_x', 'model': None, 'translation': [-3, 0, 0]}]}]}
        with open(os.path.join(self.work, 'fields.json'), 'w') as f:
            json.dump(fields, f)
        placements = {
            'placements': [
                # centre (1.5, 2) + 0.2: true; a 180° turn about the centre (origin at (2, 2))
                dict(model='a', support=0.9, **pose(1.2, 2.0, 0)),
                dict(model='a', support=0.8, **pose(2.0 + 0.1, 2.0, 180)),
                # a@2's centre is (5, 5.5); this one's centre (5, 4.5): 1 m off, false
                dict(model='a', support=0.7, **pose(5.0, 5.0, -90)),
                # the right place, the wrong model: false
                dict(model='b', support=0.6, **pose(1.5, 2.0, 0)),
            ],
            'searches': [
                {'model': 'a', 'accepted': True, 'score_m': 0.1},  # its placement is listed
                dict(model='a', accepted=False, reason='support below min_support', support=0.1,
                     confidence=0.25, terms={'seen': 0.5, 'free': 0.1}, **pose(-3.2, 0, 0)),
                {'model': 'b', 'subspaces': 100, 'accepted': 0},  # a 3D search summary
            ]}
        with open(os.path.join(self.work, 'runs', 'f.2d.json'), 'w') as f:
            json.dump(placements, f)

    def rows(self):
        out = os.path.join(self.work, 'cal.csv')
        rf.label(self.work, 'runs', out)
        with open(out) as f:
            return list(csv.DictReader(f))

    def test_labels(self):
        r = self.rows()
        self.assertEqual(len(r), 5)
        self.assertEqual([x['label'] for x in r], ['1', '1', '0', '0', '0'])
        self.assertAlmostEqual(float(r[0]['dist_same_model_m']), 0.2, places=6)
        self.assertAlmostEqual(float(r[1]['dist_same_model_m']), 0.1, places=6)
        self.assertAlmostEqual(float(r[1]['yaw_error_deg']), 0.0, places=6)  # modulo 180°
        self.assertAlmostEqual(float(r[2]['dist_same_model_m']), 1.0, places=6)
        self.assertEqual(r[2]['truth'], 'a@2')
        self.assertEqual(r[3]['dist_same_model_m'], 'nan')  # no "b" in the truth
        self.assertAlmostEqual(float(r[3]['dist_any_structure_m']), 0.0, places=6)
        self.assertAlmostEqual(float(r[4]['dist_nearest_object_m']), 0.3, places=6)  # centre to clutter

    def test_every_key_is_a_column(self):
        r = self.rows()
        for k in ('support', 'confidence', 'terms.seen', 'terms.free', 'translation_0', 'rpy_deg_2',
                  'reason', 'accepted', 'label', 'field', 'method', 'source', 'model'):
            self.assertIn(k, r[0])
        self.assertEqual(r[4]['confidence'], '0.25')
        self.assertEqual(r[4]['source'], 'search')
        self.assertEqual(r[4]['accepted'], '0')
        self.assertEqual(r[0]['accepted'], '1')
        self.assertEqual(r[0]['method'], '2d')


class Crop(unittest.TestCase):
    def test_crop_keeps_properties(self):
        d = tempfile.mkdtemp()
        src, dst = os.path.join(d, 'in.ply'), os.path.join(d, 'out.ply')
        pts = np.array([(0, 0, 1, 5), (3, 0, 2, 6), (0, -3, 3, 7), (1, 1, 4, 8)], dtype=np.float32)
        with open(src, 'wb') as f:
            f.write(b'ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n'
                    b'property float y\nproperty float z\nproperty float intensity\nend_header\n')
            f.write(pts.tobytes())
        rf.crop_ply(src, dst, -2, -2, 2, 2)
        with open(dst, 'rb') as f:
            data = f.read()
        self.assertIn(b'element vertex 2\n', data)
        body = np.frombuffer(data[data.index(b'end_header\n') + 11:], np.float32).reshape(-1, 4)
        np.testing.assert_array_equal(body, pts[[0, 3]])


if __name__ == '__main__':
    sys.exit(unittest.main())
