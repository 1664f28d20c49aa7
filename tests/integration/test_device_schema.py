"""msid-device/1's JSON Schema (docs/schemas/msid-device-1.schema.json) against the descriptions of the docs and
the tests, read by Python's tomllib: every shipped description validates, and the mistakes a schema can see
(a misspelt key, a wrong type, a bad register, a missing safe value) are refused by the schema and by msid's own
reader alike, msid's before it touches any device."""
import tomllib
from pathlib import Path

import pytest

import helpers as h

EXAMPLES = sorted((h.ROOT / "docs" / "examples").glob("*.toml"))


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_examples_validate(path):
    h.validate(tomllib.loads(path.read_text()), "msid-device-1")


BAD = [
    ('max = 2.0', 'max_stp = 2.0', "unknown key 'max_stp'"),
    ('type = "int16"', 'type = "int12"', 'type = "int12"'),
    ('register = "holding:100"', 'register = "40101"', "holding:100"),
    ('safe = 0.0', '', "no safe value"),
    ('role = "output"', 'role = "outptu"', 'role = "outptu"'),
    ('transport = "modbus"', 'transport = "profibus"', 'must be "modbus", "can" or "canopen"'),
]


@pytest.mark.parametrize("old, new, msg", BAD, ids=[b[2] for b in BAD])
def test_schema_and_msid_refuse_alike(tmp_path, old, new, msg):
    text = (h.ROOT / "docs" / "examples" / "modbus-drive.toml").read_text()
    assert old in text
    bad = text.replace(old, new, 1)
    errs = list(h.validator("msid-device-1").iter_errors(tomllib.loads(bad)))
    assert errs, "the schema accepted it"
    p = tmp_path / "bad.toml"
    p.write_text(bad)
    # port 9 (discard) on loopback: nothing listens, and nothing must be tried
    r = h.run("measure", "--device", "modbus-tcp://127.0.0.1:9", "--map", p, "--period", 64, "--lines", "1:2:31",
              "--rate", 100, "--no-plots", "-o", tmp_path / "out")
    assert r.returncode == 2 and msg in r.stderr, r.stderr
    assert "connect" not in r.stderr and not (tmp_path / "out").exists()
