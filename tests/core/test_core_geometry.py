"""Noise-free wrenches are inverted exactly, for any desk (hypothesis), and the edge cases."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hapticdesk.estimator.geometry import SurfaceFrame
from hapticdesk.estimator.intersection import intersect
from hapticdesk.files.profile import DeskProfile, SensorSpec, Surface
from hapticdesk.files.rigid_body import rotation_matrix

unit = st.floats(-1.0, 1.0, allow_nan=False)


def random_desk(draw, n_sensors: int) -> DeskProfile:
    sensors = []
    for i in range(n_sensors):
        pos = np.array([draw(st.floats(-1.0, 1.0)) for _ in range(3)])
        rpy = [draw(st.floats(-180.0, 180.0)) for _ in range(3)]
        reports = draw(st.sampled_from(["reaction", "load"]))
        sensors.append(SensorSpec(f"s{i}", pos, rotation_matrix(*rpy), reports))
    return DeskProfile("random", 1000.0, tuple(sensors), ())


def random_surface(draw) -> Surface:
    normal = np.array([draw(unit), draw(unit), draw(unit)])
    if np.linalg.norm(normal) < 0.2:
        normal = np.array([0.0, 0.0, 1.0])
    normal /= np.linalg.norm(normal)
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = helper - (helper @ normal) * normal
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    origin = np.array([draw(st.floats(-1, 1)), draw(st.floats(-1, 1)), draw(st.floats(0, 2))])
    n_vertices = draw(st.integers(3, 7))
    # a convex polygon: vertices on a circle, evenly spread with some jitter
    step = 2 * np.pi / n_vertices
    jitter = np.array([draw(st.floats(-0.4, 0.4)) for _ in range(n_vertices)])
    angles = draw(st.floats(0, 2 * np.pi)) + step * (np.arange(n_vertices) + jitter)
    radius = draw(st.floats(0.1, 1.0))
    polygon = radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)  # convex
    return Surface("s", origin, normal, u, v, polygon)


@settings(max_examples=200, deadline=None)
@given(data=st.data())
def test_noise_free_contact_is_recovered_to_1e_9(data):
    desk = random_desk(data.draw, data.draw(st.integers(3, 8)))
    surface = random_surface(data.draw)
    frame = SurfaceFrame.of(surface)
    # a point inside: a convex combination of the outline's vertices
    weights = np.array([data.draw(st.floats(0.01, 1.0)) for _ in surface.polygon])
    uv = (weights / weights.sum()) @ surface.polygon
    point = surface.to_desk(uv[0], uv[1])
    # any direction that presses into the surface (not too oblique to trust)
    d = np.array([data.draw(unit), data.draw(unit), data.draw(unit)])
    d = d - (d @ surface.normal) * surface.normal  # tangential part
    push = -surface.normal * data.draw(st.floats(0.3, 1.0)) + 0.9 * d / max(np.linalg.norm(d), 1)
    external = push / np.linalg.norm(push) * data.draw(st.floats(0.5, 300.0))
    f_o = -external
    m_o = np.cross(point, f_o)
    # sensor readings of that resultant, then back through the profile's map
    readings = np.linalg.pinv(desk.wrench_map()) @ np.concatenate([f_o, m_o])
    wrench = desk.wrench_map() @ readings
    hit = intersect([frame], wrench[:, None], 1.0, None, 0.2)
    assert hit.valid[0]
    assert np.allclose(hit.points([frame])[:, 0], point, atol=1e-9, rtol=0)


def board() -> SurfaceFrame:
    return SurfaceFrame.of(
        Surface(
            "top",
            np.array([0, 0, 0.733]),
            np.array([0, 0, 1.0]),
            np.array([1.0, 0, 0]),
            np.array([0, 1.0, 0]),
            np.array([[-0.375, -0.25], [0.375, -0.25], [0.375, 0.25], [-0.375, 0.25]]),
        )
    )


def hit_at(x: float, y: float, force_dir) -> tuple[bool, np.ndarray]:
    frame = board()
    f_o = -np.asarray(force_dir, float)
    point = np.array([x, y, 0.733])
    wrench = np.concatenate([f_o, np.cross(point, f_o)])[:, None]
    hit = intersect([frame], wrench, 1.0, [frame.project_cov(np.eye(6) * 1e-4)], 0.2)
    assert np.isfinite(hit.uv).all() and np.isfinite(hit.var_uu).all()
    return bool(hit.valid[0]), hit.points([frame])[:, 0]


def test_edges_and_corners_belong_to_the_board():
    for x, y in [(0.375, 0.0), (-0.375, 0.1), (0.0, 0.25), (0.375, 0.25), (-0.375, -0.25)]:
        ok, p = hit_at(x, y, [0, 0, -10])
        assert ok and np.allclose(p[:2], [x, y], atol=1e-12)
    ok, _ = hit_at(0.3751, 0.0, [0, 0, -10])
    assert not ok


def test_force_parallel_to_the_surface_is_not_located_and_finite():
    for direction in ([1, 0, 0], [0, 1, 0], [1, 1, -1e-9], [1, 0, -0.05]):
        ok, p = hit_at(0.1, 0.1, direction)
        assert not ok and np.isfinite(p).all()


def test_pulling_away_from_the_surface_is_not_a_touch():
    ok, _ = hit_at(0.1, 0.1, [0, 0, 10])
    assert not ok


def test_overlapping_surfaces_the_one_reached_first_wins():
    top = board()
    shelf = SurfaceFrame.of(
        Surface(
            "shelf",
            np.array([0, 0, 1.2]),
            np.array([0, 0, 1.0]),
            np.array([1.0, 0, 0]),
            np.array([0, 1.0, 0]),
            np.array([[-0.4, 0.0], [0.4, 0.0], [0.4, 0.3], [-0.4, 0.3]]),
        )
    )
    f_o = np.array([0.0, 0.0, 10.0])
    for y, expected in [(0.1, 1), (-0.1, 0)]:
        point = np.array([0.0, y, 0.733])
        wrench = np.concatenate([f_o, np.cross(point, f_o)])[:, None]
        hit = intersect([top, shelf], wrench, 1.0, None, 0.2)
        assert hit.surface[0] == expected


def test_shear_is_the_drag_along_the_surface_over_the_press_into_it():
    from hapticdesk.estimator.contacts import SHEAR_CAP
    from hapticdesk.estimator.kernel_geometry import shear_of

    forces = np.array([[3.0, 4.0, -10.0], [3.0, 4.0, -10.0], [0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    # a top pressed with 10 N and dragged with 5 N; an upright panel pushed with 4 N and
    # dragged with sqrt(109) N; no force; a force along the surface alone (capped, finite)
    want = [0.5, np.sqrt(109.0) / 4.0, 0.0, SHEAR_CAP]
    for f, n, w in zip(forces, normals, want, strict=True):
        one = shear_of(float(f @ n), float(np.linalg.norm(f)), SHEAR_CAP, 1.0 / SHEAR_CAP)
        assert one == pytest.approx(w, rel=1e-12)
