"""The package is citable and says what it is: CITATION.cff, LICENSE, CHANGELOG.md and the
pyproject metadata agree with each other, and the type marker ships with the package."""

import re
import tomllib
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO.parent / "shared" / "paper" / "linear-dashpot-restitution.tex"
PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]


@pytest.fixture(scope="module")
def citation():
    return yaml.safe_load((REPO / "CITATION.cff").read_text(encoding="utf-8"))


def _person_or_entity(author):
    return bool(author.get("name") or author.get("family-names"))


def test_citation_cff_parses_with_the_required_keys(citation):
    # The keys Citation File Format 1.2.0 requires at the top level.
    assert {"cff-version", "message", "title", "authors"} <= set(citation)
    assert citation["cff-version"] == "1.2.0"
    assert citation["message"].strip() and citation["title"].strip()
    assert citation["authors"] and all(_person_or_entity(a) for a in citation["authors"])
    # It describes this package as pyproject.toml does.
    assert citation["version"] == PROJECT["version"]
    assert citation["license"] == PROJECT["license"]
    assert [a["name"] for a in citation["authors"]] == [a["name"] for a in PROJECT["authors"]]


def test_citation_references_the_paper(citation):
    papers = [r for r in citation.get("references", []) +
              ([citation["preferred-citation"]] if "preferred-citation" in citation else [])
              if "dashpot" in r["title"].lower()]
    assert len(papers) == 1
    paper = papers[0]
    assert {"type", "title", "authors"} <= set(paper)
    assert paper["authors"][0]["family-names"] == "Bartz"
    if not PAPER.is_file():
        pytest.skip(f"the paper is not at {PAPER}: its title is not compared")
    tex = PAPER.read_text(encoding="utf-8")
    assert paper["title"] == re.search(r"\\title\{(.*?)\}", tex).group(1)
    assert "Bartz" in re.search(r"\\author(?:\[\])?\{(.*?)\\thanks", tex).group(1)


def test_license_file_matches_pyproject():
    text = (REPO / "LICENSE").read_text(encoding="utf-8")
    assert PROJECT["license"] == "MIT" and text.startswith("MIT License")
    assert re.search(r"Copyright \(c\) \d{4} dashpot developers", text)
    assert "LICENSE" in PROJECT["license-files"]
    # A licence expression and a licence classifier together are refused by setuptools.
    assert not any(c.startswith("License ::") for c in PROJECT["classifiers"])


def test_type_marker_is_package_data():
    assert (REPO / "src" / "dashpot" / "py.typed").is_file()
    package_data = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"]["dashpot"]
    assert "py.typed" in package_data
    assert "Typing :: Typed" in PROJECT["classifiers"]


def test_changelog_keeps_a_changelog():
    text = (REPO / "CHANGELOG.md").read_text(encoding="utf-8")
    assert text.startswith("# Changelog")
    assert "keepachangelog.com" in text
    releases = re.findall(r"^## \[([^\]]+)\]", text, flags=re.M)
    assert releases and releases[0] == "Unreleased"
    sections = set(re.findall(r"^### (\w+)", text, flags=re.M))
    assert sections and sections <= {"Added", "Changed", "Deprecated", "Removed", "Fixed",
                                     "Security"}
