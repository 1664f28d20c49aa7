"""Files are written with the umask's permissions. Before the fix write_frf and
write_model wrote 0600 (their temporary file came from mkstemp), where the command line, Design.save
and export wrote 0644; the command line's atomic writer gave 0644 whatever the umask. Now every
writer creates mode 0666 less the umask: 0644 under the default umask 022, 0664 under 002, 0600 under
077."""
import os
import stat
import subprocess
import warnings

import pytest

import msid
from child import small_case


@pytest.fixture
def objects():
    d, rec = small_case()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = msid.frf(rec, design=d)
        m = msid.fit(f, method="ml", order=2)
    return d, f, m


def mode(p):
    return stat.S_IMODE(os.stat(p).st_mode)


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_every_writer_follows_the_umask(tmp_path, objects, umask):
    d, f, m = objects
    want = 0o666 & ~umask
    old = os.umask(umask)
    try:
        msid.write_frf(tmp_path / "frf.json", f)
        msid.write_model(tmp_path / "model.json", m)
        d.save(tmp_path / "design.json")
        msid.export(f, tmp_path / "frf.csv")
        msid.write_frf(tmp_path / "frf.json", f)   # replacing a file: the new one's mode
        b = os.environ.get("MSID_BIN")
        if b:
            r = subprocess.run([b, "excite", "--period", "64", "--lines", "1:3:20", "-o", tmp_path / "cli.json"],
                               capture_output=True, text=True, timeout=120)
            assert r.returncode == 0, r.stderr
    finally:
        os.umask(old)
    for name in ("frf.json", "model.json", "design.json", "frf.csv") + (("cli.json",) if b else ()):
        assert mode(tmp_path / name) == want, (name, oct(mode(tmp_path / name)), oct(want))
    assert sorted(p.name for p in tmp_path.iterdir() if ".tmp" in p.name) == []   # no temporary left


def test_write_errors_name_the_file_not_its_temporary(tmp_path, objects):
    d, f, m = objects
    ro = tmp_path / "ro"
    ro.mkdir()
    os.chmod(ro, 0o500)
    try:
        if os.access(ro, os.W_OK):
            pytest.skip("running as a user that writes everywhere (root)")
        with pytest.raises(PermissionError) as e:
            msid.write_frf(ro / "frf.json", f)
        assert str(e.value).endswith(f"cannot write '{ro / 'frf.json'}': Permission denied"), str(e.value)
    finally:
        os.chmod(ro, 0o700)


def test_write_errors_name_the_file_as_root_too(tmp_path, objects):
    """A directory where the file should be: the error names the file, never the temporary."""
    d, f, m = objects
    (tmp_path / "frf.json").mkdir()
    with pytest.raises(OSError) as e:
        msid.write_frf(tmp_path / "frf.json", f)
    assert f"cannot write '{tmp_path / 'frf.json'}'" in str(e.value) and ".tmp" not in str(e.value), str(e.value)
    assert [p.name for p in tmp_path.iterdir()] == ["frf.json"]
