"""Regenerate the example outputs shown in README.md from the current code.

Each example is a ``dashpot`` command; the README shows it with what it prints between the
markers ``<!-- output: NAME -->`` and ``<!-- end output -->`` (a fenced ``text`` block holding
``$ command`` and the output). This script runs every command verbatim, as a user would, in a
fresh folder, and rewrites those blocks, so the README cannot drift from the code::

    .venv/bin/python scripts/readme_examples.py          # rewrite README.md
    .venv/bin/python scripts/readme_examples.py --check  # exit 1 where it differs

The recording is the shared ping-pong one (``../shared/data/pingpong-erickson/pingpong.wav``
beside the repository, with its scene ``data/pingpong-erickson/scene.yaml``); where it is
absent, the workflow's synthetic ``light-ball-audio`` scene is written and used instead (and
the script says so: the README is meant to show the real recording). Both scenes ask for the
noise model (``noise: true``): one run gives the quick start's block (the deterministic fits)
and the noise section's (the fits under the noise model).
``tests/test_readme_examples.py`` checks that the README holds what this script would write.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
README = REPO / "README.md"
PINGPONG = Path("../shared/data/pingpong-erickson/pingpong.wav")  # relative to the repository
PINGPONG_SCENE = Path("data/pingpong-erickson/scene.yaml")
SYNTHETIC = "light-ball-audio"  # the workflow's synthetic scene used where PINGPONG is absent

# name -> (arguments after `dashpot`, with {recording} and {scene}; which lines to show). The
# ping-pong scene asks for the noise model (noise: true): one run gives both blocks, the quick
# start's without the noise fits' lines and the noise section's with only those.
ANALYZE = ("analyze", "{recording}", "--scene", "{scene}", "-o", "out")
EXAMPLES = {
    "analyze": (ANALYZE, "deterministic"),
    "analyze-noise": (ANALYZE, "noise"),
}
NOISE_PREFIX = "  noise"  # how report_text starts the lines of the fits under the noise model
OMITTED = "  ..."
BLOCK = re.compile(r"(<!-- output: (?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- end output -->)",
                   re.S)


def shared_recording_present(repo=REPO):
    """Whether the shared ping-pong recording is beside the repository."""
    return (repo / PINGPONG).is_file()


def _synthetic_scene(folder):
    """Write the workflow's synthetic light-ball scene into `folder`; (recording, scene)
    relative to it."""
    import yaml

    from dashpot.pipeline import write_synthetic_scene

    spec = yaml.safe_load((REPO / "config" / "config.yaml").read_text())["synthetic"][SYNTHETIC]
    spec["scene"] = {**(spec.get("scene") or {}), "noise": True}  # as the ping-pong scene
    scene = write_synthetic_scene(folder / SYNTHETIC, spec, name=SYNTHETIC)
    recording = yaml.safe_load(scene.read_text())["recording"]
    return Path(SYNTHETIC) / recording, Path(SYNTHETIC) / "scene.yaml"


def _shown(lines, which):
    """The lines of an output the README shows: all, those before the fits under the noise
    model (the first line and the deterministic fits), or the first line and the noise
    model's with their notes (the last group :func:`dashpot.report_text` prints); "  ..."
    stands where lines are left out.

    Raises
    ------
    RuntimeError
        The output has no line of the kind asked for (then the README's text around the block
        no longer describes it).
    """
    noise = [index for index, line in enumerate(lines) if line.startswith(NOISE_PREFIX)]
    if which != "all" and not noise:
        raise RuntimeError("the example printed no fit under the noise model")
    if which == "all":
        return lines
    if which == "deterministic":
        return [*lines[:noise[0]], OMITTED]
    return [lines[0], OMITTED, *lines[noise[0]:]]  # the noise group comes last, notes too


def generate(repo=REPO, names=None):
    """Run the examples in a fresh folder.

    Parameters
    ----------
    repo : pathlib.Path
        The repository root (its ``data/`` and ``../shared/data`` are what the commands read).
    names : sequence of str, optional
        The examples to run (default: all of ``EXAMPLES``).

    Returns
    -------
    dict of str -> str
        Example name -> the block's text: ``$ command`` and the lines shown, each ending in a
        newline.

    Raises
    ------
    RuntimeError
        A command exited with a nonzero status (its standard error is in the message).
    """
    outputs = {}
    with tempfile.TemporaryDirectory(prefix="readme-") as temporary:
        folder = Path(temporary) / "work"
        folder.mkdir()
        if shared_recording_present(repo):
            # The README's paths, as seen from the repository root: ../shared beside the
            # working folder and data/ inside it.
            (folder / "data").symlink_to(repo / "data", target_is_directory=True)
            (Path(temporary) / "shared").symlink_to((repo / "../shared").resolve(),
                                                    target_is_directory=True)
            recording, scene = PINGPONG, PINGPONG_SCENE
        else:
            recording, scene = _synthetic_scene(folder)
        environment = {**os.environ, "COLUMNS": "100", "NO_COLOR": "1"}
        printed = {}  # each command is run once, however many blocks show it
        for name in names or EXAMPLES:
            arguments, which = EXAMPLES[name]
            argv = tuple(part.format(recording=recording, scene=scene) for part in arguments)
            if argv not in printed:
                run = subprocess.run([sys.executable, "-m", "dashpot", *argv], cwd=folder,
                                     capture_output=True, text=True, env=environment)
                if run.returncode != 0:
                    raise RuntimeError(f"dashpot {' '.join(argv)} exited with "
                                       f"{run.returncode}: {run.stderr.strip()}")
                printed[argv] = run.stdout.rstrip("\n").split("\n")
            lines = _shown(printed[argv], which)
            outputs[name] = "".join(f"{line}\n" for line in [f"$ dashpot {' '.join(argv)}",
                                                             *lines])
    return outputs


def render(text, outputs):
    """The README `text` with each marked block replaced by its example's output.

    Raises
    ------
    KeyError
        A block names an example this script does not know.
    """
    def block(match):
        body = outputs[match.group("name")]
        return f"{match.group(1)}```text\n{body}```\n{match.group(4)}"

    return BLOCK.sub(block, text)


def marked_names(text):
    """Names of the marked blocks of a README text, in order."""
    return [match.group("name") for match in BLOCK.finditer(text)]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="change nothing; exit 1 where README.md differs")
    args = parser.parse_args(argv)
    if not shared_recording_present():
        print(f"note: {PINGPONG} not found; the examples run on the synthetic scene "
              f"{SYNTHETIC}", file=sys.stderr)
    text = README.read_text(encoding="utf-8")
    missing = set(EXAMPLES) - set(marked_names(text))
    if missing:
        print(f"README.md has no block for {', '.join(sorted(missing))}", file=sys.stderr)
        return 1
    new = render(text, generate())
    if args.check:
        print("README.md is up to date" if new == text else "README.md differs")
        return 0 if new == text else 1
    if new != text:
        README.write_text(new, encoding="utf-8")
        print("README.md: example outputs rewritten")
    else:
        print("README.md is up to date")
    return 0


if __name__ == "__main__":
    sys.exit(main())
