"""World models through the bindings (docs/world.md)."""
import json

import numpy as np
import pytest

import sonar3d


def test_world_model_seabed_objects_and_files(tmp_path):
    # A 6 x 4 m seabed with relief every 2 cm and a tank standing on it at (3, 2).
    step = 0.02
    xs, ys = np.meshgrid(np.arange(0, 6, step), np.arange(0, 4, step))
    z = 0.1 * np.sin(xs) - 1.0
    pts = np.column_stack([xs.ravel(), ys.ravel(), z.ravel()]).astype(np.float32)
    cat = tmp_path / "cat.yaml"
    cat.write_text("models:\n  - {name: tank, reference: tank, symmetry: full}\n")
    placements = tmp_path / "p.json"
    placements.write_text(json.dumps({
        "format": "sonar3d-placements", "version": 1,
        "placements": [{"model": "tank", "score_m": 0.1, "residual_median_m": 0.01,
                        "T_world_model": [[1, 0, 0, 3], [0, 1, 0, 2], [0, 0, 1, -1], [0, 0, 0, 1]]}]}))
    w = sonar3d.world_model(pts, str(placements), str(cat), seabed=sonar3d.SeabedConfig(lod_cells_m=[0.05, 0.2]),
                            output=str(tmp_path / "W"))
    assert [o["id"] for o in w["objects"]] == ["tank_0"]
    np.testing.assert_allclose(w["objects"][0]["T_world_model"][:3, 3], [3, 2, -1])
    assert [l["cell_m"] for l in w["seabed"]] == pytest.approx([0.05, 0.2])
    fine = w["seabed"][0]
    assert fine["vertices"].shape[1] == 3 and fine["triangles"].shape[1] == 3
    assert fine["triangles"].max() < len(fine["vertices"])
    # The mesh follows the surface it was made from.
    v = fine["vertices"]
    assert np.median(np.abs(v[:, 2] - (0.1 * np.sin(v[:, 0]) - 1.0))) < 0.01
    graph = json.loads((tmp_path / "W" / "graph.json").read_text())
    assert graph["format"] == "sonar3d-world"
    assert (tmp_path / "W" / "world.glb").stat().st_size > 0


def test_world_model_refuses_an_unknown_model(tmp_path):
    pts = np.zeros((10, 3), np.float32)
    cat = tmp_path / "cat.yaml"
    cat.write_text("models:\n  - {name: pillar, reference: pillar}\n")
    placements = tmp_path / "p.json"
    placements.write_text(json.dumps({
        "format": "sonar3d-placements", "version": 1,
        "placements": [{"model": "tank", "T_world_model": np.eye(4).tolist()}]}))
    with pytest.raises(sonar3d.Error, match="names model 'tank'"):
        sonar3d.world_model(pts, str(placements), str(cat))


def flat_seabed_and_tank_catalogue(tmp_path):
    """A flat 12 x 4 m seabed at z = -1 (points every 5 cm) and a catalogue of the reference tank."""
    step = 0.05
    xs, ys = np.meshgrid(np.arange(0, 12, step), np.arange(0, 4, step))
    pts = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, -1.0)]).astype(np.float32)
    cat = tmp_path / "cat.yaml"
    cat.write_text("models:\n  - {name: tank, reference: tank, symmetry: full}\n")
    return pts, cat


def test_world_model_given_connections(tmp_path):
    # Two tanks on a flat seabed with no pipe between them: a connection given in YAML is kept,
    # with the distance between the footprints, marked given and not found.
    pts, cat = flat_seabed_and_tank_catalogue(tmp_path)
    placements = tmp_path / "p.json"
    placements.write_text(json.dumps({
        "format": "sonar3d-placements", "version": 1,
        "placements": [{"model": "tank", "T_world_model": [[1, 0, 0, x], [0, 1, 0, 2],
                                                           [0, 0, 1, -1], [0, 0, 0, 1]]}
                       for x in (2, 10)]}))
    given = tmp_path / "c.yaml"
    given.write_text("connections:\n  - {from: tank_0, to: tank_1, kind: cable}\n")
    w = sonar3d.world_model(pts, str(placements), str(cat), seabed=sonar3d.SeabedConfig(lod_cells_m=[0.1]),
                            connections=str(given))
    assert len(w["connections"]) == 1
    c = w["connections"][0]
    assert (c["from"], c["to"], c["kind"], c["given"], c["found"]) == \
        ("tank_0", "tank_1", "cable", True, False)
    assert c["length_m"] == pytest.approx(8.0, abs=1e-6)
    given.write_text("connections:\n  - {from: tank_0, to: tank_7}\n")
    with pytest.raises(sonar3d.Error, match="c.yaml:2: 'tank_7' names no placed object"):
        sonar3d.world_model(pts, str(placements), str(cat), seabed=sonar3d.SeabedConfig(lod_cells_m=[0.1]),
                            connections=str(given))


def test_world_model_seabed_colours(tmp_path):
    # A flat seabed, red west of x = 3 and blue east of it, every 5 cm: 20 cm vertices take the
    # colour of their half (linear mean of sRGB bytes); no colours, no seabed colours.
    step = 0.05
    xs, ys = np.meshgrid(np.arange(0, 6, step), np.arange(0, 4, step))
    pts = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, -1.0)]).astype(np.float32)
    colors = np.where(pts[:, :1] < 3, [[200, 40, 30]], [[20, 60, 210]]).astype(np.uint8)
    cat = tmp_path / "cat.yaml"
    cat.write_text("models:\n  - {name: tank, reference: tank, symmetry: full}\n")
    placements = tmp_path / "p.json"
    placements.write_text(json.dumps({"format": "sonar3d-placements", "version": 1,
                                      "placements": []}))
    w = sonar3d.world_model(pts, str(placements), str(cat), seabed=sonar3d.SeabedConfig(lod_cells_m=[0.2]), colors=colors)
    lod = w["seabed"][0]
    assert lod["colors"].shape == lod["vertices"].shape
    assert (lod["color_points"] > 0).all()
    west = lod["vertices"][:, 0] < 2.8
    east = lod["vertices"][:, 0] > 3.2
    to_srgb = lambda c: np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055) * 255
    np.testing.assert_allclose(to_srgb(lod["colors"][west]), [[200, 40, 30]] * west.sum(), atol=1)
    np.testing.assert_allclose(to_srgb(lod["colors"][east]), [[20, 60, 210]] * east.sum(), atol=1)
    plain = sonar3d.world_model(pts, str(placements), str(cat), seabed=sonar3d.SeabedConfig(lod_cells_m=[0.2]))
    assert plain["seabed"][0]["colors"].shape == (0, 3)
    with pytest.raises(sonar3d.Error, match="colors must be an N×3 uint8 array"):
        sonar3d.world_model(pts, str(placements), str(cat), colors=colors[:5])


def test_world_model_confidence_threshold(tmp_path):
    # Two tanks, one below the file's threshold: unconfirmed (listed, never connected), and a
    # connection given to it refused; min_confidence overrides the file's threshold.
    pts, cat = flat_seabed_and_tank_catalogue(tmp_path)
    placements = tmp_path / "p.json"
    placements.write_text(json.dumps({
        "format": "sonar3d-placements", "version": 1, "settings": {"min_confidence": 0.5},
        "placements": [
            {"model": "tank", "confidence": 0.9,
             "T_world_model": [[1, 0, 0, 2], [0, 1, 0, 2], [0, 0, 1, -1], [0, 0, 0, 1]]},
            {"model": "tank", "confidence": 0.3,
             "T_world_model": [[1, 0, 0, 10], [0, 1, 0, 2], [0, 0, 1, -1], [0, 0, 0, 1]]}]}))
    w = sonar3d.world_model(pts, str(placements), str(cat), seabed=sonar3d.SeabedConfig(lod_cells_m=[0.1]))
    assert w["min_confidence"] == pytest.approx(0.5)
    assert [o["confirmed"] for o in w["objects"]] == [True, False]
    assert w["objects"][1]["confidence"] == pytest.approx(0.3)
    given = tmp_path / "c.yaml"
    given.write_text("connections:\n  - {from: tank_0, to: tank_1}\n")
    with pytest.raises(sonar3d.Error, match="'tank_1' is an unconfirmed placement"):
        sonar3d.world_model(pts, str(placements), str(cat), seabed=sonar3d.SeabedConfig(lod_cells_m=[0.1]),
                            connections=str(given))
    w = sonar3d.world_model(pts, str(placements), str(cat), seabed=sonar3d.SeabedConfig(lod_cells_m=[0.1]),
                            connections=str(given), min_confidence=0.2)
    assert [o["confirmed"] for o in w["objects"]] == [True, True]
    assert len(w["connections"]) == 1
    with pytest.raises(sonar3d.Error, match=r"min_confidence must lie in \[0, 1\]"):
        sonar3d.world_model(pts, str(placements), str(cat), min_confidence=1.5)


def test_relocalize_config_and_bad_worlds(tmp_path):
    # The configuration is the command's (one declaration): bounds name the field.
    c = sonar3d.RelocalizeConfig(piece_m=0)
    c.registration.search_m = 0.8  # a view: sets c's own registration
    assert c.registration.search_m == 0.8 and c.to_dict()["piece_m"] == 0
    assert c.to_dict()["registration"]["search_m"] == 0.8
    assert "num_threads" not in c.to_dict()["registration"]  # the relocalisation's own
    with pytest.raises(Exception, match="min_overlap_fraction"):
        sonar3d.RelocalizeConfig(min_overlap_fraction=1.5).validate()
    # The survey carved again with its relocalised navigation (survey B of diff_surveys): off by
    # default, a voxel size when asked.
    assert sonar3d.RelocalizeConfig().map_voxel_m == 0
    assert sonar3d.RelocalizeConfig(map_voxel_m=0.02).to_dict()["map_voxel_m"] == 0.02
    with pytest.raises(Exception, match="map_voxel_m"):
        sonar3d.RelocalizeConfig(map_voxel_m=-1).validate()
    # A world directory that is missing, or has no seabed: one clear error each.
    with pytest.raises(Exception, match="does not exist"):
        sonar3d.relocalize(str(tmp_path / "ds"), str(tmp_path / "nowhere"))
    w = tmp_path / "w"
    w.mkdir()
    (w / "graph.json").write_text('{"format": "sonar3d-world", "version": 1, "seabed": []}')
    with pytest.raises(Exception, match="has no seabed"):
        sonar3d.relocalize(str(tmp_path / "ds"), str(w))


def test_world_model_config_is_the_commands():
    c = sonar3d.WorldModelConfig()
    assert c.seabed.lod_cells_m == [0.05, 0.2, 1.0] and c.min_confidence is None
    c.seabed.lod_cells_m = [0.1, 0.2]
    c.min_confidence = 0.3
    d = c.to_dict()
    assert d["seabed"]["lod_cells_m"] == [0.1, 0.2] and d["min_confidence"] == 0.3
    with pytest.raises(Exception, match="lod_cells_m"):
        c.seabed.lod_cells_m = [0.1, -1.0]
    with pytest.raises(Exception, match="lod_cells_m"):
        sonar3d.WorldModelConfig(seabed=sonar3d.SeabedConfig(lod_cells_m=[0.1, 0.25])).validate()
