"""The README is the front door: it fits a screen and a minute, its two commands come first and
are the ones that work (the test command is the one CI runs), every link goes somewhere, its
extras are the ones pyproject.toml defines, and its measurements live in the docs, not here."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text("utf-8")
FIRST_SCREEN = "\n".join(README.splitlines()[:25])


def test_the_readme_fits_a_screen_and_a_minute() -> None:
    assert len(README.splitlines()) <= 200


def test_the_two_commands_are_on_the_first_screen() -> None:
    assert "pip install -e '.[demo]' && hapticdesk demo" in FIRST_SCREEN
    assert "&& bash scripts/test.sh" in FIRST_SCREEN
    # the test command is CI's: .ci/run runs the README's command, not a copy of its steps
    ci = (ROOT / ".ci" / "run").read_text("utf-8")
    assert re.search(r"^bash scripts/test\.sh$", ci, re.M)
    # and the extra the demo command installs is one pyproject.toml defines
    assert "demo" in _extras()


def test_every_link_goes_to_a_file_of_the_repository() -> None:
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", README)
    local = [link for link in links if not re.match(r"[a-z]+://", link)]
    assert local, "the README links no page"
    assert [link for link in local if not (ROOT / link).is_file()] == []


def test_each_guide_is_linked() -> None:
    for guide in sorted((ROOT / "docs" / "guides").glob("*.md")):
        assert f"(docs/guides/{guide.name})" in README, guide.name


def test_the_extras_table_names_every_extra_and_no_other() -> None:
    table = set(re.findall(r"^\| `\[([\w-]+)\]` \|", README, re.M))
    assert table == set(_extras())


def test_each_contract_links_the_page_that_states_it() -> None:
    for page in ("mqtt.md", "http.md", "files.md", "profile.md", "layout.md", "hooks.md"):
        assert f"(docs/reference/{page})" in README, page


def test_measurements_and_history_are_in_the_docs_not_here() -> None:
    # a measured figure carries its command and date: in docs/results, not in the README
    assert not re.search(r"\b20\d\d-\d\d-\d\d\b", README)
    assert not re.search(r"\bissue \d+\b|\(was ", README)


def _extras() -> list[str]:
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))
    return list(pyproject["project"]["optional-dependencies"])
