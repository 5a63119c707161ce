"""Video mapping through the bindings (docs/video.md): a simulated camera image of a box on a
seabed, colours back onto a cloud and a mesh, hidden points left uncoloured, bad inputs."""
import numpy as np
import pytest

import sonar3d

SAND = np.array([0.8, 0.7, 0.3], np.float32)
RED = np.array([0.9, 0.1, 0.1], np.float32)


def plane(size):
    h = size / 2
    v = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], np.float32)
    return sonar3d.Mesh(v, np.array([[0, 1, 2], [0, 2, 3]], np.int32))


def box(sx, sy, sz, z0):
    v = np.array([[x, y, z] for z in (z0, z0 + sz) for y in (-sy / 2, sy / 2)
                  for x in (-sx / 2, sx / 2)], np.float32)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    t = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return sonar3d.Mesh(v, np.array(t, np.int32))


def down_camera():
    cam = sonar3d.CameraIntrinsics(width=160, height=120, fx=100, fy=100, cx=79.5, cy=59.5)
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # +z_camera = -z_world: looking down
    T[2, 3] = 3.0
    return cam, T


def test_render_and_texture_a_cloud_and_a_mesh():
    seabed, block = plane(6.0), box(0.6, 0.6, 0.6, 0.0)
    cam, T = down_camera()
    img = sonar3d.render_camera([seabed, block], [SAND, RED], cam, T, ambient=1.0,
                                attenuation_per_m=0.0)
    assert img.shape == (120, 160, 3) and img.dtype == np.float32
    np.testing.assert_allclose(img[60, 80], RED, atol=1e-4)  # the box top under the camera
    np.testing.assert_allclose(img[5, 5], SAND, atol=1e-4)
    assert cam.project(np.array([0.0, 0.0, 1.0])) == pytest.approx((79.5, 59.5))

    rng = np.random.default_rng(1)
    seabed_pts = np.column_stack([rng.uniform(-1.2, 1.2, 4000), rng.uniform(-0.9, 0.9, 4000),
                                  np.zeros(4000)]).astype(np.float32)
    top_pts = np.column_stack([rng.uniform(-0.25, 0.25, 500), rng.uniform(-0.25, 0.25, 500),
                               np.full(500, 0.6)]).astype(np.float32)
    pts = np.vstack([seabed_pts, top_pts])
    colors, views = sonar3d.texture_cloud(pts, [(cam, T, img)],
                                          sonar3d.TextureConfig(point_spacing_m=0.03))
    assert colors.shape == (4500, 3) and views.shape == (4500,)
    under = np.max(np.abs(pts[:4000, :2]), axis=1) < 0.25
    away = np.max(np.abs(pts[:4000, :2]), axis=1) > 0.45
    assert under.sum() > 50 and np.all(views[:4000][under] == 0)  # hidden by the box
    seen_sand = colors[:4000][away & (views[:4000] > 0)]
    assert len(seen_sand) > 1000
    assert np.abs(seen_sand - SAND).max() < 1e-3
    assert np.all(views[4000:] == 1)
    assert np.abs(colors[4000:] - RED).max() < 1e-3

    mesh, mcolors, mviews = sonar3d.texture_mesh(
        block, [(cam, T, img)], sonar3d.MeshTextureConfig(texel_m=0.05))
    v = mesh.vertices
    top = (np.abs(v[:, 2] - 0.6) < 1e-5) & (np.max(np.abs(v[:, :2]), axis=1) < 0.28)
    bottom = np.abs(v[:, 2]) < 1e-5
    assert top.sum() > 50 and np.all(mviews[top] == 1)
    assert np.abs(mcolors[top] - RED).max() < 1e-3
    assert np.all(mviews[bottom] == 0)  # the box's underside: no camera sees it

    # An occluder (a 0.2 m plate 0.1 m over the box top's middle) hides what it covers and takes
    # no colour; the mesh returned is still the box alone.
    plate = box(0.2, 0.2, 0.02, 0.7)
    omesh, ocolors, oviews = sonar3d.texture_mesh(
        block, [(cam, T, img)], sonar3d.MeshTextureConfig(texel_m=0.05), occluders=plate)
    assert omesh.vertices.shape == v.shape
    under_plate = top & (np.max(np.abs(v[:, :2]), axis=1) < 0.07)
    clear = top & (np.max(np.abs(v[:, :2]), axis=1) > 0.16)
    assert under_plate.sum() > 3 and np.all(oviews[under_plate] == 0)
    assert clear.sum() > 20 and np.all(oviews[clear] == 1)

    # silhouette_weight reaches the texturer (one frame: the weight does not change a mean of one)
    # and is validated.
    _, wcolors, wviews = sonar3d.texture_mesh(
        block, [(cam, T, img)], sonar3d.MeshTextureConfig(texel_m=0.05, silhouette_weight=1.0))
    assert np.array_equal(wviews, mviews)
    with pytest.raises(sonar3d.Error, match=r"silhouette_weight must be in \(0, 1\]"):
        sonar3d.texture_mesh(block, [(cam, T, img)],
                             sonar3d.MeshTextureConfig(silhouette_weight=0.0))


def test_bad_views_give_clear_errors():
    cam, T = down_camera()
    img = np.zeros((120, 160, 3), np.float32)
    pts = np.zeros((1, 3), np.float32)
    with pytest.raises(sonar3d.Error, match=r"views\[0\] must be"):
        sonar3d.texture_cloud(pts, [(cam, T)])
    bad = img.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(sonar3d.Error, match="not finite"):
        sonar3d.texture_cloud(pts, [(cam, T, bad)])
    with pytest.raises(sonar3d.Error, match="size"):
        sonar3d.texture_cloud(pts, [(cam, T, img[:60])])
    with pytest.raises(sonar3d.Error, match="camera/camera.yaml is missing"):
        sonar3d.read_camera_frames(".")


def test_camera_world_transform_and_poses_config():
    T = np.asarray(sonar3d.camera_world_transform("aoneus"))
    assert np.allclose(T[:3, :3] @ [1, 2, 3], [-2, -3, 1])
    assert np.allclose(np.asarray(sonar3d.camera_world_transform("0 -1 0 0 0 -1 1 0 0")), T)
    with pytest.raises(sonar3d.Error, match="not a rotation"):
        sonar3d.camera_world_transform("2 0 0 0 1 0 0 0 1")
    c = sonar3d.TexturePosesConfig(camera_world="holoocean", neus_frame="normalized")
    assert c.camera_world == "holoocean" and c.neus_frame == "normalized"
    c.validate()
    with pytest.raises(sonar3d.Error, match="warn_dark_share"):
        c.warn_dark_share = 2.0
