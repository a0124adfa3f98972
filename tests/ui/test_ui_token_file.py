"""`--token-file PATH` (``ui`` and ``run --ui``): the page's token from a file's first line,
where ``--token`` put it in every user's ``ps``. A file that gives no usable token is refused
naming the file, before a new layout is written; the token is in no error, log line or
address; a file open to other users is warned about, as ssh does for a key."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

httpx = pytest.importorskip("httpx")
pytest.importorskip("uvicorn")

from hapticdesk.cli import main  # noqa: E402

from .conftest import stop_process, watch_address  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TOKEN = "long-enough-s3cret"


@pytest.fixture(autouse=True)
def _no_token_in_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("HAPTICDESK_UI_TOKEN", raising=False)


def _token_file(folder: Path, text: str, mode: int = 0o600) -> Path:
    path = folder / "token.txt"
    path.write_text(text)
    path.chmod(mode)
    return path


@pytest.mark.parametrize(
    ("text", "said"),
    [
        (None, "cannot read the page's token file (--token-file): No such file or directory"),
        ("", "the page's token file (--token-file) is empty"),
        ("\n  \n", "the page's token file (--token-file) is empty"),
        ("\n" + TOKEN + "\n", "the page's token file (--token-file) has no token on its first"),
        ("short-s3cret\n"[:7] + "\n", "a token of 7 characters lets other machines guess it"),
    ],
    ids=["missing", "empty", "blank", "first-line-blank", "short"],
)
def test_ui_refuses_a_token_file_that_gives_no_token_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str | None, said: str
) -> None:
    token = tmp_path / "token.txt" if text is None else _token_file(tmp_path, text)
    layout = tmp_path / "new.yaml"
    argv = ["ui", "--layout", str(layout), "--host", "0.0.0.0", "--port", "0"]
    assert main([*argv, "--token-file", str(token)]) == 2
    err = capsys.readouterr().err
    assert err == f"hapticdesk ui: error: {token}: {said}" + err.split(said, 1)[1]
    assert err.count("\n") == 1 and "s3cret" not in err
    assert not layout.exists()  # refused before the new layout is written


def test_a_token_file_that_is_a_folder_or_not_text_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["ui", "--layout", str(tmp_path / "new.yaml"), "--port", "0", "--token-file"]
    assert main([*argv, str(tmp_path)]) == 2
    assert "cannot read the page's token file (--token-file): Is a directory" in (
        capsys.readouterr().err
    )
    binary = tmp_path / "token.bin"
    binary.write_bytes(b"\xff\xfe\x00token")
    assert main([*argv, str(binary)]) == 2
    assert f"{binary}: the page's token file (--token-file) is not text" in capsys.readouterr().err


def test_token_and_token_file_together_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    token = _token_file(tmp_path, TOKEN)
    with pytest.raises(SystemExit) as ended:
        main(["ui", "--token", TOKEN, "--token-file", str(token), "--port", "0"])
    assert ended.value.code == 2
    err = capsys.readouterr().err
    assert "argument --token-file: not allowed with argument --token\n" in err
    assert TOKEN not in err


def test_run_takes_token_file_only_with_ui_and_holds_its_length_rule(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    layout = tmp_path / "buttons.yaml"
    shutil.copy(ROOT / "examples" / "layouts" / "buttons.yaml", layout)
    token = _token_file(tmp_path, "s3cret\n")
    run = ["run", "--layout", str(layout), "--source", "sim:nothing.yaml"]
    assert main([*run, "--token-file", str(token)]) == 2
    assert capsys.readouterr().err == (
        "hapticdesk run: error: --token-file: is the token of the page --ui serves: give --ui too\n"
    )
    scene = tmp_path / "scene.yaml"
    scene.write_text("name: s\ndesk: kitamura2017\ntimeline:\n  - idle: 0.1\n")
    run = ["run", "--layout", str(layout), "--source", f"sim:{scene}", "--speed", "0"]
    assert main([*run, "--ui", "0.0.0.0:0", "--token-file", str(token)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"hapticdesk run: error: {token}: a token of 6 characters lets")
    assert "s3cret" not in err


def _serve(argv: list[str], env: dict[str, str]) -> tuple[subprocess.Popen[str], str, list[str]]:
    """``hapticdesk ARGV`` started; its page's address, once printed, and its stderr lines."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "hapticdesk", "-v", "-v", *argv],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
        env=env,
    )
    lines: list[str] = []
    found, url = watch_address(proc, lines)
    deadline = time.monotonic() + 60
    while not found.wait(0.2):  # (a refusal ends the process: no need to wait the minute)
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            proc.wait(5)
            raise AssertionError("".join(lines))
    return proc, url[0], lines


@pytest.mark.parametrize("command", ["ui", "run"])
def test_the_real_server_asks_for_the_token_from_the_file(tmp_path: Path, command: str) -> None:
    """`ui --token-file` and `run --ui … --token-file`, served for real: the page and its API
    answer only with the file's token (its first line, without the newline or a second
    line), the printed address is bare, no line of the debug log carries the token, and a
    file open to other users is warned about."""
    token = _token_file(tmp_path, f"  {TOKEN}  \nsecond line\n", mode=0o644)
    layout = tmp_path / "buttons.yaml"
    shutil.copy(ROOT / "examples" / "layouts" / "buttons.yaml", layout)
    scene = tmp_path / "taps.yaml"
    scene.write_text(
        "name: t\ndesk: kitamura2017\nunits: cm\nquiet_s: 2.0\ntimeline:\n"
        + "  - tap: {point: [0, 0], wait_s: 0.5}\n" * 20
    )
    serve = {
        "ui": ["ui", "--layout", str(layout), "--source", f"sim:{scene}", "--port", "0"],
        "run": ["run", "--layout", str(layout), "--source", f"sim:{scene}", "--ui", "0"],
    }[command]
    env = {k: v for k, v in os.environ.items() if k != "HAPTICDESK_UI_TOKEN"}
    proc, base, lines = _serve([*serve, "--token-file", str(token)], env)
    try:
        assert TOKEN not in base and "asks for its token" in "".join(lines)
        assert httpx.get(base + "api/layout").status_code == 401
        wrong = {"authorization": f"Bearer {TOKEN} second line"}
        assert httpx.get(base + "api/layout", headers=wrong).status_code == 401
        right = httpx.get(base + "api/layout", headers={"authorization": f"Bearer {TOKEN}"})
        assert right.status_code == 200 and right.text == layout.read_text()
    finally:
        stop_process(proc)
    said = "".join(lines)
    assert f"hapticdesk ui: warning: {token}: the page's token file is open to other users " in (
        said
    )
    assert "(mode 0644); `chmod 600" in said
    assert TOKEN not in said and "s3cret" not in said, said


def test_a_token_file_kept_to_its_owner_is_not_warned_about(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from hapticdesk.plugins.ui.page_token import page_token

    token = _token_file(tmp_path, TOKEN + "\n")
    assert page_token(None, str(token)) == (TOKEN, str(token))
    assert capsys.readouterr().err == ""
    token.chmod(0o640)
    assert page_token(None, str(token)) == (TOKEN, str(token))
    assert "open to other users (mode 0640)" in capsys.readouterr().err
