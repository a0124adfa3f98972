"""Replaying a recording keeps memory flat whatever the file's size (issue 11 item 4).

Each replay runs in a fresh interpreter and reads its own peak resident size (``VmHWM`` in
/proc/self/status; not ``ru_maxrss``, which Linux carries over fork and exec from the test run
that starts it, so in a long session both replays would report the runner's size and any
growth would pass): replaying a file four times larger must not need more memory than a
block's worth more.
"""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

NAMES = ["fl", "fr", "bl", "br"]
HEADER = "t," + ",".join(f"{s}_{a}" for s in NAMES for a in ("fx", "fy", "fz", "mx", "my", "mz"))

REPLAY = textwrap.dedent(
    """
    import sys
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.plugins.replay import open_replay

    source = open_replay(sys.argv[1], load_profile("kitamura2017"), speed=0)
    samples = 0
    with source:
        for block in source.blocks():
            samples += len(block.t)
    with open("/proc/self/status") as status:
        peak = next(line.split()[1] for line in status if line.startswith("VmHWM:"))
    print(samples, peak)  # KiB
    """
)


def write_csv(path, rows: int, chunk: int = 20_000) -> None:
    rng = np.random.default_rng(0)
    with path.open("w") as fh:
        fh.write(HEADER + ",note\n")
        for start in range(0, rows, chunk):
            n = min(chunk, rows - start)
            table = np.hstack([(start + np.arange(n))[:, None] / 1200.0, rng.normal(size=(n, 24))])
            body = np.char.add(
                np.array([",".join(f"{v:.6g}" for v in r) for r in table[:50]]), ",x"
            )
            # 50 distinct rows repeated, with their own times: fast to write, same to read
            lines = np.resize(body, n)
            times = np.char.mod("%.6f", table[:, 0])
            tails = np.array([s.split(",", 1)[1] for s in lines])
            fh.write("\n".join(np.char.add(np.char.add(times, ","), tails)) + "\n")


def peak_kib(path) -> tuple[int, int]:
    out = subprocess.run(
        [sys.executable, "-c", REPLAY, str(path)], capture_output=True, text=True, check=True
    )
    samples, kib = out.stdout.split()
    return int(samples), int(kib)


@pytest.mark.skipif(sys.platform != "linux", reason="/proc/self/status is Linux's")
def test_replay_memory_does_not_grow_with_the_file(tmp_path):
    small, large = tmp_path / "small.csv", tmp_path / "large.csv"
    write_csv(small, 100_000)  # ~17 MB
    write_csv(large, 400_000)  # ~68 MB
    n_small, kib_small = peak_kib(small)
    n_large, kib_large = peak_kib(large)
    assert (n_small, n_large) == (100_000, 400_000)
    size_growth_mib = (large.stat().st_size - small.stat().st_size) / 2**20
    # reading whole would grow by a few times the file's growth (~50 MB); blocks by ~nothing
    assert (kib_large - kib_small) / 1024 < 0.2 * size_growth_mib, (kib_small, kib_large)


def test_an_npz_of_thousands_of_members_is_refused_before_they_are_opened(tmp_path):
    """The fuzzing pass: a 12 MB NPZ of 60,000 tiny extra columns took 3.4 GB and 32 s,
    each member opened as a stream of its own. More than 1,024 members are refused at once."""
    from hapticdesk.errors import ConfigError
    from hapticdesk.files.recording_io import read_recording
    from hapticdesk.files.recording_npz import MAX_NPZ_MEMBERS

    sensors = ["fl", "fr", "bl", "br"]
    columns = {"t": np.arange(10.0)}
    columns.update(
        {f"{s}_{a}": np.zeros(10) for s in sensors for a in ("fx", "fy", "fz", "mx", "my", "mz")}
    )
    columns.update({f"x{k}": np.zeros(10) for k in range(MAX_NPZ_MEMBERS)})
    path = tmp_path / "many.npz"
    np.savez(path, **columns)
    with pytest.raises(ConfigError, match=r"many\.npz: 1,049 members; .* at most 1,024"):
        read_recording(path, sensors)


def test_a_csv_wider_than_any_desk_is_refused_at_its_header(tmp_path):
    """The fuzzing pass: a 164 MB CSV of 4,000 columns took 1.38 GB to read, every extra
    column kept. A header of more than 1,024 columns (as many as an NPZ's members) is refused
    at the first column beyond them; one of 1,024 is read, its extras kept."""
    from hapticdesk.errors import ConfigError
    from hapticdesk.files.recording_io import read_recording

    def wide(columns: int):
        path = tmp_path / f"wide{columns}.csv"
        extras = [f"x{k}" for k in range(columns - 25)]
        row = ",".join(["0"] * columns)
        path.write_text(",".join([HEADER, *extras]) + "\n" + f"{row}\n" * 3)
        return path

    with pytest.raises(ConfigError) as refused:
        read_recording(wide(1_025), NAMES)
    assert str(refused.value) == (
        f"{tmp_path}/wide1025.csv:1:1025: 1,025 columns; a recording has one per channel "
        "(time, the desk's channels, a few more): at most 1,024 are read"
    )
    rec = read_recording(wide(1_024), NAMES)
    assert (len(rec), len(rec.extra)) == (3, 1_024 - 25)


def test_a_wide_recording_is_read_in_fewer_samples_a_block(tmp_path):
    """A block holds at most 16,384 × 64 values: 1,024 samples of 1,024 columns (16,384 of
    them held 128 MB a block, and a replay of a 164 MB file 360 MB; now 223 MB)."""
    from hapticdesk.files.recording_io import RecordingBlocks

    path = tmp_path / "wide.csv"
    extras = [f"x{k}" for k in range(1_024 - 25)]
    rows = "".join(f"{i / 1200:.6f}," + ",".join(["0"] * 1_023) + "\n" for i in range(3_000))
    path.write_text(",".join([HEADER, *extras]) + "\n" + rows)
    with RecordingBlocks(path, NAMES) as reader:
        lengths = [len(block) for block in reader.blocks()]
    assert (sum(lengths), max(lengths)) == (3_000, 1_024)
