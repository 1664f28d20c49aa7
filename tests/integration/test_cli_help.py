"""`--help` and `-h` work everywhere: every command and bench subcommand prints its
usage on stdout and exits 0, whatever else is on the line; `msid bench --help` lists every
benchmark, can and modbus included. Typed option getters and parse_enum: one message naming
the option and the valid values, exit 2. Negative controls: an unknown option is still refused."""
import pytest

import helpers as h

COMMANDS = [["excite"], ["frf"], ["frf", "--method", "lpm"], ["demo"], ["fit"], ["fit", "--order", "auto"],
            ["validate"], ["compare"], ["modes"], ["can"], ["modbus"], ["device"], ["device", "check"],
            ["bench", "frf"], ["bench", "fit"], ["bench", "lpm"], ["bench", "io"], ["bench", "target"],
            ["bench", "wcet"], ["bench", "can"], ["bench", "modbus"], ["bench", "ticks"]]


@pytest.mark.parametrize("flag", ["--help", "-h"])
@pytest.mark.parametrize("cmd", COMMANDS, ids=" ".join)
def test_help_everywhere(cmd, flag):
    r = h.run(*cmd, flag)
    assert r.returncode == 0, r.stderr
    assert "usage" in r.stdout.lower() and r.stderr == ""


@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_help_wins_over_bad_options(flag):
    # the help is printed before anything is parsed: a bad value does not hide it
    r = h.run("frf", "--period", "x", "--bogus", flag)
    assert r.returncode == 0 and "usage: msid frf" in r.stdout


@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_bench_lists_every_benchmark(flag):
    r = h.run("bench", flag)
    assert r.returncode == 0
    for name in ("frf", "fit", "lpm", "io", "can", "modbus", "ticks", "target", "wcet"):
        assert f"\n  {name} " in r.stdout, name


def test_bench_without_name_is_usage_error():
    r = h.run("bench")
    assert r.returncode == 2 and "can" in r.stderr and "modbus" in r.stderr


def test_unknown_bench_names_the_known_ones():
    r = h.run("bench", "nope")
    assert r.returncode == 2 and "unknown subcommand 'bench nope'" in r.stderr and "modbus" in r.stderr


@pytest.mark.parametrize("args,msg", [
    (["frf", "--period", 64, "--lines", 1, "--experiment", "e.csv", "--dft", "slow", "-o", "f.json"],
     "--dft must be auto, stream or fft (got 'slow')"),
    (["frf", "--period", 64, "--lines", 1, "--experiment", "e.csv", "--transient", "x", "-o", "f.json"],
     "--transient must be flag, drop or off (got 'x')"),
    (["excite", "--period", 64, "--lines", 1, "--phases", "x", "-o", "d.json"],
     "--phases must be random or schroeder (got 'x')"),
    (["excite", "--period", 64, "--lines", 1, "--periods", "-3", "-o", "d.json"], "--periods"),
    (["frf", "--method", "lpm", "--threads", 0, "--experiment", "e.csv", "-o", "f.json"], "--threads must be 1..64"),
    (["frf", "--method", "lpm", "--order", 9, "--experiment", "e.csv", "-o", "f.json"], "--order must be 0..8"),
    (["bench", "frf", "--only", "x"], "--only: 'x' is not a non-negative integer"),
])
def test_typed_options_one_message(tmp_path, args, msg):
    n = 256
    h.write_csv(tmp_path / "e.csv", {"u1": [float(k % 64 == 0) for k in range(n)], "y1": [0.5] * n})
    r = h.run(*args, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert msg in r.stderr and r.stderr.count("error:") == 1
    assert [p.name for p in tmp_path.iterdir()] == ["e.csv"]   # nothing written


def test_unknown_option_still_refused():
    r = h.run("validate", "--bogus")
    assert r.returncode == 2 and "unknown option --bogus" in r.stderr and "did you mean" not in r.stderr


@pytest.mark.parametrize("args,near", [(["fit", "--methd", "ml"], "--method"),
                                       (["frf", "--skip-period", "1"], "--skip-periods"),
                                       (["frf", "--experimnet", "e.csv"], "--experiment"),
                                       (["fit", "--allow-unstabel"], "--allow-unstable")])
def test_misspelt_option_gets_did_you_mean(args, near):
    r = h.run(*args)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert f"unknown option {args[1]} (did you mean {near}?)" in lines[0]


def test_usage_lists_every_command_of_the_table():
    # the usage text is made from the command table: every command runs, every listed one exists
    r = h.run("--help")
    assert r.returncode == 0
    listed = [ln.split()[0] for ln in r.stdout.splitlines() if ln.startswith("  ") and not ln.startswith("   ")]
    assert listed == ["measure", "excite", "frf", "demo", "fit", "modes", "validate", "compare", "can", "modbus",
                      "device", "plot", "export", "import", "bench", "version"]
    for name in listed:
        if name in ("version", "demo", "measure"):
            continue
        assert h.run(name, "--help").returncode == 0, name


@pytest.mark.parametrize("typo, meant", [("fti", "fit"), ("frff", "frf"), ("mesure", "measure"), ("validat", "validate")])
def test_misspelt_command_gets_did_you_mean(typo, meant):
    r = h.run(typo)
    assert r.returncode == 2
    assert f"unknown command '{typo}' (did you mean '{meant}'?)" in r.stderr


def test_unrelated_command_gets_no_guess():
    r = h.run("xyzzyq")
    assert r.returncode == 2 and "did you mean" not in r.stderr and "unknown command 'xyzzyq'" in r.stderr
