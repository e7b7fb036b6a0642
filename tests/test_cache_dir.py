"""Where the surrogate tables are cached: an explicit folder, else $DASHPOT_CACHE_DIR, else the
platform's user cache folder (platformdirs)."""

import sys
from pathlib import Path

import platformdirs
import pytest

from dashpot.physics.surrogate import cache_dir


def test_default_is_the_user_cache_folder(monkeypatch, tmp_path):
    monkeypatch.delenv("DASHPOT_CACHE_DIR", raising=False)
    assert cache_dir() == platformdirs.user_cache_path("dashpot", appauthor=False)
    assert cache_dir().name in ("dashpot", "Cache")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="XDG base directories: Linux")
def test_default_follows_xdg_cache_home_on_linux(monkeypatch, tmp_path):
    monkeypatch.delenv("DASHPOT_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "dashpot"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_dir() == tmp_path / "home" / ".cache" / "dashpot"


def test_environment_and_argument_override_the_default(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setenv("DASHPOT_CACHE_DIR", str(tmp_path / "env"))
    assert cache_dir() == tmp_path / "env"
    assert cache_dir(tmp_path / "given") == tmp_path / "given"
    assert cache_dir(str(tmp_path / "given")) == Path(tmp_path / "given")
    # An empty variable is no setting.
    monkeypatch.setenv("DASHPOT_CACHE_DIR", "")
    assert cache_dir() == tmp_path / "xdg" / "dashpot" or not sys.platform.startswith("linux")
