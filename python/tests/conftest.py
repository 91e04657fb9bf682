"""Fixtures: the built CLI (SPARSELOOP_CLI, set by CTest) and a small rendered sequence."""
import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def cli_path():
    cli = os.environ.get("SPARSELOOP_CLI", str(REPO / "build" / "bin" / "sparseloop"))
    if not os.path.exists(cli):
        pytest.fail(f"the sparseloop CLI is not built: {cli} (set SPARSELOOP_CLI)")
    return cli


@pytest.fixture(scope="session")
def cli():
    return cli_path()


@pytest.fixture(scope="session")
def sequence(tmp_path_factory, cli):
    """The CLI tests' loop sequence: aerial circuit, 60 frames of 640x480, 2 laps (about 4 s)."""
    out = tmp_path_factory.mktemp("seq")
    subprocess.run([cli, "render", "--world", "aerial", "--plan", "circuit", "--frames", "60",
                    "--laps", "2", "--seed", "1", "--out", str(out)],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return out
