"""book/data/benchmark.json, which chapter 8 shows, must come from the current code and settings."""

import json
from pathlib import Path

import pytest

from closedloop import __version__
from closedloop.studies.benchmark import DEFAULT_SETTINGS, source_fingerprint, study_entries

DATA = Path(__file__).resolve().parents[1] / "book" / "data" / "benchmark.json"
REGENERATE = "regenerate it with `make benchmark-data` (closedloop benchmark --json book/data/benchmark.json)"


@pytest.fixture(scope="module")
def data():
    assert DATA.exists(), f"{DATA} is missing; {REGENERATE}"
    return json.loads(DATA.read_text())


def test_data_file_is_not_stale(data):
    assert data["source_fingerprint"] == source_fingerprint(), (
        f"{DATA.name} was made by other library sources than these (fingerprint "
        f"{data['source_fingerprint'][:12]} != {source_fingerprint()[:12]}): {REGENERATE}")
    assert data["closedloop_version"] == __version__, f"made by closedloop {data['closedloop_version']}: {REGENERATE}"


def test_data_file_is_the_default_study(data):
    assert data["settings"] == DEFAULT_SETTINGS.as_dict(), f"not the default settings of the code: {REGENERATE}"
    assert {r["formulation"] for r in data["rows"]} == {e.key for e in study_entries()}, REGENERATE
    assert {r["case"] for r in data["rows"]} == set(DEFAULT_SETTINGS.cases)
