"""`msid frf` on records held as arrays: the arrays written as .npy files, the command line run on them
(its FRF, or its message with the files named as msid.frf names the arrays, records[k])."""
import re

import numpy as np

from conftest import msid as cli

import msid


def save_npy(tmp, recs):
    paths = []
    for k, r in enumerate(recs):
        p = tmp / f"e{k + 1}.npy"
        np.save(p, r)
        paths.append(p)
    return paths


def columns(nu, ny):
    return ",".join([f"u{j + 1}={j + 1}" for j in range(nu)] + [f"y{i + 1}={nu + i + 1}" for i in range(ny)])


def cli_args(tmp, recs, nu, *args):
    exp = []
    for p in save_npy(tmp, recs):
        exp += ["--experiment", p]
    return ["frf", *exp, "--columns", columns(nu, recs[0].shape[1] - nu), *args, "-o", tmp / "frf.json"]


def cli_frf(tmp, recs, nu, *args):
    cli(*cli_args(tmp, recs, nu, *args))
    return msid.read_frf(tmp / "frf.json")


def cli_error(tmp, recs, nu, *args):
    """The command line's message for these records, the files named as msid.frf names the arrays."""
    r = cli(*cli_args(tmp, recs, nu, *args), check=False)
    assert r.returncode != 0, "msid frf accepted the records"
    m = re.search(r"msid frf: error: (.*)", r.stderr)
    assert m, r.stderr
    msg = m.group(1)
    for k in range(len(recs)):
        msg = msg.replace(str(tmp / f"e{k + 1}.npy"), f"records[{k}]")
    return msg
