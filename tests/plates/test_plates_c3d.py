"""A C3D force plate as a desk: the map of each TYPE against a known press and against
ezc3d's own centre of pressure, on files made here and on the real recordings."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.estimator import ContactEstimator
from hapticdesk.files.c3d import open_c3d
from hapticdesk.files.forceplate import plate_desk, read_plate_recording

from .conftest import (
    PlateSpec,
    Press,
    reference_cop_mm,
    shared_file,
    write_plate_file,
    y_up_corners,
    z_up_corners,
)

rng = np.random.default_rng(3)
KISTLER_CAL = np.diag([500.0, 500.0, 1000.0, 300e3, 250e3, 150e3])  # N/V, N·mm/V
KISTLER_CAL += rng.normal(0, 5.0, (6, 6)) * np.array([1, 1, 1, 100, 100, 100])[:, None]


def located_lab(path, plate=1):
    """hapticdesk's point for each sample (lab, m; NaN where not located), and the desk."""
    file = open_c3d(path)
    desk = plate_desk(file, plate)
    rec = read_plate_recording(path, desk.profile, file)
    block = ContactEstimator(desk.profile).push(rec.t, rec.wrench)
    out = np.full((len(rec.t), 3), np.nan)
    pts = np.stack([block.x, block.y, block.z], axis=1)[block.located]
    out[block.located] = desk.to_lab(pts)
    return out, desk, rec


SPECS = {
    "type2-z-up-mm": (PlateSpec(2, z_up_corners(), (1.5, -0.8, -40.0)), (0.61, 0.32, 0.0)),
    "type2-y-up-metres-Nm-origin-written-positive": (
        PlateSpec(2, y_up_corners(), (0.002, 0.001, 0.0225), "m", "Nm"),
        (0.9, 0.0, 0.62),
    ),
    "type3-kistler": (PlateSpec(3, z_up_corners(half=(0.3, 0.45)), (210.0, 350.0, -53.0)), None),
    "type4-calibrated-y-up": (
        PlateSpec(4, y_up_corners(), (0.0, 0.0, -41.0), calibration=KISTLER_CAL),
        (1.1, 0.0, 0.4),
    ),
    "type1-centre-of-pressure": (PlateSpec(1, z_up_corners(), (0.0, 0.0, -30.0)), None),
}


@pytest.mark.parametrize("name", list(SPECS))
def test_a_press_is_located_where_it_was_on_each_type(tmp_path, name):
    spec, point = SPECS[name]
    centre = spec.corners_m.mean(axis=0)
    down = spec.rotation()[:, 2]  # the plate's z: into the plate
    if point is None:
        point = tuple(centre + spec.rotation() @ np.array([0.07, -0.11, 0.0]))
    # a person's push: 600 N into the plate, 60 N of shear along the plate's x; the
    # reaction (what the channels carry) is its opposite
    push = 600.0 * down + 60.0 * spec.rotation()[:, 0]
    path = write_plate_file(tmp_path / "p.c3d", [spec], [Press(point, tuple(-push))])
    lab, desk, _ = located_lab(path)
    got = lab[~np.isnan(lab[:, 0])]
    assert len(got) > 0.9 * 1000  # (1 s of load at 1 kHz)
    assert np.abs(got - np.array(point)).max() < 1e-4  # 0.1 mm, the lab frame
    if spec.type != 1:  # ezc3d reads TYPE 1 its own way (no example, says its code)
        ref = reference_cop_mm(path, 1)[~np.isnan(lab[:, 0])] * spec.metres  # (POINT:UNITS)
        assert np.abs(got - ref).max() < 1e-4


def test_a_plate_that_gives_the_force_on_it_is_read_as_a_load(tmp_path):
    spec = PlateSpec(2, z_up_corners(), (0.0, 0.0, -40.0))
    point = (0.58, 0.27, 0.0)
    # the channels carry the person's push on the plate (down), not the plate's reaction
    path = write_plate_file(tmp_path / "load.c3d", [spec], [Press(point, (0.0, 0.0, -700.0))])
    lab, desk, _ = located_lab(path)
    assert desk.profile.sensors[0].reports == "load"
    got = lab[~np.isnan(lab[:, 0])]
    assert len(got) > 900 and np.abs(got - np.array(point)).max() < 1e-4


def test_the_zero_comes_from_the_zero_frames(tmp_path):
    offsets = np.array([3.0, -2.0, 25.0, 400.0, -300.0, 50.0])  # N, N·mm: a drifted amplifier
    spec = PlateSpec(2, z_up_corners(), (0.0, 0.0, -40.0), offsets=offsets, zero=(1, 10))
    point = (0.45, 0.47, 0.0)
    path = write_plate_file(tmp_path / "z.c3d", [spec], [Press(point, (0.0, 0.0, 500.0))])
    lab, desk, rec = located_lab(path)
    assert np.isnan(lab[:200, 0]).all()  # (the plate unloaded for 0.2 s: nothing located)
    assert np.abs(lab[~np.isnan(lab[:, 0])] - np.array(point)).max() < 1e-4
    # and the noise for the covariances is measured on those frames, not a default
    assert desk.profile.estimation.zeroed


def test_without_its_zero_frames_the_offset_would_be_a_load(tmp_path):
    offsets = np.array([3.0, -2.0, 25.0, 400.0, -300.0, 50.0])
    spec = PlateSpec(2, z_up_corners(), (0.0, 0.0, -40.0), offsets=offsets, zero=(0, 0))
    path = write_plate_file(tmp_path / "nz.c3d", [spec], [Press((0.45, 0.47, 0.0), (0, 0, 500.0))])
    _, _, rec = located_lab(path)
    assert abs(rec.channels[0, 2] - 25.0) < 1e-9  # [0, 0]: the channels are taken as zeroed


def test_a_plate_holds_no_jump_over(tmp_path):
    # a foot's strike is a jump from a still plate: held over for its first sample it began
    # a millisecond late (the real BTS files), now for the hold's 2 samples at 1 kHz; a lab
    # amplifier's readings hold nothing
    spec, point = SPECS["type2-z-up-mm"]
    push = 600.0 * spec.rotation()[:, 2]
    path = write_plate_file(tmp_path / "p.c3d", [spec], [Press(point, tuple(-push))])
    file = open_c3d(path)
    desk = plate_desk(file, 1)
    assert desk.profile.estimation.hold_jumps is False
    rec = read_plate_recording(path, desk.profile, file)
    held = desk.profile.with_estimation(hold_jumps=True)
    first = [
        int(np.argmax(ContactEstimator(p).push(rec.t, rec.wrench).in_contact))
        for p in (desk.profile, held)
    ]
    hold = ContactEstimator(held).stage_settings.jump_hold_n
    assert hold == 2 and first[1] == first[0] + hold


def test_two_plates_of_one_file_each_a_desk(tmp_path):
    a = PlateSpec(2, z_up_corners(centre=(0.3, 0.2, 0.0)), (0.0, 0.0, -40.0))
    b = PlateSpec(3, z_up_corners(centre=(1.0, 0.2, 0.0), half=(0.3, 0.45)), (210.0, 350.0, -53.0))
    presses = [Press((0.35, 0.1, 0.0), (0, 0, 300.0)), Press((1.1, 0.4, 0.0), (5, 0, 800.0))]
    path = write_plate_file(tmp_path / "two.c3d", [a, b], presses)
    for plate, press in ((1, presses[0]), (2, presses[1])):
        lab, desk, _ = located_lab(path, plate)
        assert desk.profile.sensors[0].name == f"plate{plate}"
        assert np.abs(lab[~np.isnan(lab[:, 0])] - np.array(press.point_m)).max() < 1e-4


def test_a_plate_that_is_not_there_is_named(tmp_path):
    spec = PlateSpec(2, z_up_corners(), (0.0, 0.0, -40.0))
    path = write_plate_file(tmp_path / "one.c3d", [spec], [Press((0.5, 0.4, 0.0), (0, 0, 1.0))])
    with pytest.raises(ConfigError, match="one.c3d has 1 force plate: expected --plate 1"):
        plate_desk(open_c3d(path), 2)


def test_a_zero_range_past_the_end_is_an_error(tmp_path):
    spec = PlateSpec(2, z_up_corners(), (0.0, 0.0, -40.0), zero=(500, 510))
    path = write_plate_file(tmp_path / "far.c3d", [spec], [Press((0.5, 0.4, 0.0), (0, 0, 1.0))])
    with pytest.raises(ConfigError, match=r"FORCE_PLATFORM:ZERO names frames 500–510"):
        plate_desk(open_c3d(path), 1)


def test_a_broken_file_is_refused_with_its_name(tmp_path):
    path = tmp_path / "broken.c3d"
    path.write_bytes(b"\x02\x50" + bytes(300))
    with pytest.raises(ConfigError, match="broken.c3d"):
        open_c3d(path)


# --- the real recordings (../shared/data/forceplates, read where they lie) -----------------


@pytest.mark.parametrize(
    ("name", "plates"), [("BTS.c3d", (1, 4, 5)), ("Qualisys.c3d", (1, 2)), ("FP_Type3.c3d", (1,))]
)
def test_the_map_alone_gives_ezc3ds_point_on_the_real_files(name, plates):
    path = shared_file(name)
    file = open_c3d(path)
    for plate in plates:
        desk = plate_desk(file, plate)
        rec = read_plate_recording(path, desk.profile, file)
        w = rec.channels @ desk.profile.wrench_map().T
        loaded = np.linalg.norm(w[:, :3], axis=1) > 50.0
        assert loaded.any()
        f, m = w[loaded, :3], w[loaded, 3:]
        top = np.stack([-m[:, 1] / f[:, 2], m[:, 0] / f[:, 2], np.zeros(len(f))], axis=1)
        ref = reference_cop_mm(path, plate)[loaded]
        assert np.abs(desk.to_lab(top) * 1000.0 - ref).max() < 1e-6


def test_ezc3ds_pinned_frames():
    fp3 = shared_file("FP_Type3.c3d")
    file = open_c3d(fp3)
    desk = plate_desk(file, 1)
    w = read_plate_recording(fp3, desk.profile, file).channels @ desk.profile.wrench_map().T
    assert desk.plate.type == 3
    assert abs(np.linalg.norm(w[0, :3]) - 886.40) < 0.01
    point = desk.to_lab(np.array([-w[0, 4] / w[0, 2], w[0, 3] / w[0, 2], 0.0])) * 1000
    assert np.allclose(point, [446.651, 291.147, -5.749], atol=1e-3)
    q = shared_file("Qualisys.c3d")
    file = open_c3d(q)
    desk = plate_desk(file, 1)
    w = read_plate_recording(q, desk.profile, file).channels @ desk.profile.wrench_map().T
    point = desk.to_lab(np.array([-w[0, 4] / w[0, 2], w[0, 3] / w[0, 2], 0.0])) * 1000
    assert np.linalg.norm(w[0, :3]) < 0.3  # (a frame with 0.2 N on it)
    assert np.allclose(point, [228.81, 118.30, 0.0], atol=0.01)


@pytest.mark.parametrize(
    ("name", "plates"), [("BTS.c3d", (1, 4, 5)), ("Qualisys.c3d", (1, 2)), ("FP_Type3.c3d", (1,))]
)
def test_the_estimator_follows_ezc3ds_point_on_the_real_files(name, plates):
    """The issue's floor, on every loaded sample (> 50 N) whatever the point's speed: within
    2 mm at the 95th percentile, located on 90 % of them (docs/forceplates.md)."""
    path = shared_file(name)
    for plate in plates:
        lab, desk, rec = located_lab(path, plate)
        ref = reference_cop_mm(path, plate) / 1000.0
        w = rec.channels @ desk.profile.wrench_map().T
        loaded = np.linalg.norm(w[:, :3], axis=1) > 50.0
        got = ~np.isnan(lab[loaded, 0])
        assert got.mean() >= 0.9
        err = np.linalg.norm(lab[loaded][got] - ref[loaded][got], axis=1)
        assert np.percentile(err, 95) < 0.002
