"""Fixtures of the Python module's tests. ctest runs them with /usr/bin/python3, PYTHONPATH at the
build tree's package (build/python) and the paths below in the environment."""
import json
import os
import pathlib

import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("LIDARTAG_SOURCE_DIR",
                                         pathlib.Path(__file__).resolve().parents[2]))
DEMO = SOURCE_DIR / "pcaps" / "demo.pcap"
DEMO_TRUTH = SOURCE_DIR / "pcaps" / "demo.truth.json"
DEMO_SCENE = SOURCE_DIR / "pcaps" / "demo.yaml"
DEMO_CONFIG = SOURCE_DIR / "config" / "demo.yaml"
DEMO_SIZES = {"tag_sizes_m": [0.8, 0.6], "families": ["tag16h5"]}


@pytest.fixture(scope="session")
def demo():
    if not DEMO.exists():
        pytest.skip(f"no demo capture at {DEMO}")
    return DEMO


@pytest.fixture(scope="session")
def truth():
    return json.loads(DEMO_TRUTH.read_text())


@pytest.fixture(scope="session")
def demo_rotations(demo):
    import lidartag
    return list(lidartag.read(demo))


def _built_program(variable, what):
    """The built program ctest names in `variable`; the test is skipped without it."""
    path = os.environ.get(variable)
    if not path or not os.path.exists(path):
        pytest.skip(f"{variable} ({what}) not given")
    return path


@pytest.fixture(scope="session")
def lidartag_cli():
    return _built_program("LIDARTAG_CLI", "the built lidartag tool")


@pytest.fixture(scope="session")
def lidartagd():
    return _built_program("LIDARTAGD", "the built lidartagd")


def expect_matches_truth(result, truth_rotation, tolerance_m=0.05):
    """Every truth tag found once with its ID, position within tolerance, nothing else."""
    found = {(d.family, d.id): d for d in result}
    assert len(found) == len(result), "a tag was reported twice"
    assert len(result) == len(truth_rotation["tags"]), [repr(d) for d in result]
    for tag in truth_rotation["tags"]:
        d = found[(tag["family"], tag["id"])]
        error = sum((a - b) ** 2 for a, b in zip(d.position, tag["position"])) ** 0.5
        assert error < tolerance_m, (tag, d.position)
