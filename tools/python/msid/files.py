"""msid-frf/1 and msid-model/1 files (docs/frf-format.md, docs/model-format.md): read into the types of
msid.types, written back atomically (temporary file, then rename), keeping every key they do not hold.

    f = read_frf("frf.json")      # an msid.FRF
    m = read_model("model.json")  # an msid.Model
    write_frf("copy.json", f); write_model("copy.json", m)

read_frf also reads the FRF files of other tools (.sNp, .uff/.unv, .csv, .mat): those need the compiled
module msid._msid, whose readers `msid import` uses; msid-frf/1 and msid-model/1 need NumPy only.
"""
import errno
import json
import os
import secrets
from typing import Any, Dict, Optional, Union

from ._compiled import ext as _ext
from .types import FRF, FRF_FORMAT, MODEL_FORMAT, FormatError, Model, frf_from_doc, frf_to_doc, model_to_doc

PathLike = Union[str, "os.PathLike[str]"]

# frf_from_doc, frf_to_doc and model_to_doc are the document form, re-exported for the package's own use
__all__ = ["read_frf", "import_frf", "write_frf", "read_model", "write_model", "FRF", "Model", "FormatError"]

def _os_error(e: OSError, what: str) -> OSError:
    """The OSError `e` of the same type and errno, its message `what: reason` (naming the file the caller
    named, not a temporary one)."""
    if e.errno is None:
        return OSError(f"{what}: {e}")
    return type(e)(e.errno, f"{what}: {e.strerror}")


def _load(path: PathLike, fmt: str) -> Dict[str, Any]:
    """A document file as a dict: OSError when it cannot be read (missing, a directory, no permission),
    FormatError (a ValueError) when it is not the msid document `fmt` (not UTF-8 JSON text, another format)."""
    path = os.fspath(path)
    try:
        with open(path, "r", encoding="utf-8") as fh:
            doc = json.load(fh)
    except OSError as e:
        raise _os_error(e, f"cannot read '{path}'") from None
    except UnicodeDecodeError as e:
        raise FormatError(f"'{path}' is not an {fmt} file: byte 0x{e.object[e.start]:02x} at offset {e.start} is "
                          "not UTF-8 text (JSON)") from None
    except json.JSONDecodeError as e:
        raise FormatError(f"'{path}' is not valid JSON: {e}") from None
    except RecursionError:
        raise FormatError(f"'{path}' is not an {fmt} file: JSON nested too deeply") from None
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        got = doc.get("format") if isinstance(doc, dict) else None
        raise FormatError(f"'{path}': format is {json.dumps(got)}, expected \"{fmt}\"")
    return doc


def _write_atomic(path: PathLike, doc: Dict[str, Any]) -> None:
    """JSON to a temporary file next to `path`, then rename: a failed write leaves no file. The file
    gets the umask's permissions (as open() and the command line give): created with mode 0666, which
    the umask reduces (0644 under the default umask 022). Errors name `path`, never the temporary."""
    text = json.dumps(doc, indent=1, allow_nan=False)
    _write_text_atomic(path, text + "\n")


def _write_text_atomic(path: PathLike, text: str) -> None:
    path = os.fspath(path)
    d = os.path.dirname(os.path.abspath(path))
    tmp = None
    try:
        for _ in range(100):   # a name of its own: O_EXCL, as mkstemp, but with the umask's mode
            cand = os.path.join(d, f"{os.path.basename(path)}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
            try:
                fd = os.open(cand, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666)
            except FileExistsError:
                continue
            tmp = cand
            break
        else:
            raise FileExistsError(errno.EEXIST, "no free temporary name")
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
        tmp = None
    except OSError as e:
        raise _os_error(e, f"cannot write '{path}'") from None
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)


def _other_tool(path: PathLike) -> bool:
    """Whether `path` names an FRF of another tool by its extension (.sNp, .uff, .unv, .csv, .mat)."""
    ext = os.path.splitext(os.fspath(path))[1].lower()
    return ext in (".uff", ".unv", ".csv", ".mat") or (len(ext) in (4, 5) and ext[1] == "s" and ext[-1] == "p"
                                                      and ext[2:-1].isdigit())


def read_frf(path: PathLike) -> FRF:
    """Read an msid-frf/1 file (docs/frf-format.md) into an FRF; an FRF measured by another tool
    (Touchstone .sNp, UFF 58 .uff/.unv, CSV, idfrd .mat) is imported as msid.import_frf does (which
    needs the compiled module)."""
    if _other_tool(path):
        return import_frf(path)
    return frf_from_doc(_load(path, FRF_FORMAT), f"'{path}'")


def import_frf(path: PathLike, format: Optional[str] = None) -> FRF:
    """An FRF file of any format msid reads, as an msid.FRF: msid-frf/1, or one measured by another tool
    (format "touchstone", "uff", "csv" or "mat"; default: by the extension and content), converted by
    `msid import`'s readers, in the compiled module (docs/frf-format.md, "FRFs from other tools"). A
    network analyser's or modal suite's FRF is continuous-time without a sample time; without standard
    deviations it has no covariance (msid.fit then fits it unweighted, with no p-value). ValueError with
    msid's message for a file msid refuses, OSError for one it cannot read."""
    path = os.fspath(path)
    text = _ext().import_frf(path, "" if format is None else str(format))
    return frf_from_doc(json.loads(text), f"'{path}'")


def write_frf(path: PathLike, frf: FRF) -> None:
    """Write an FRF as msid-frf/1. Keys the FRF does not know (from its meta) are kept as read;
    a new FRF (FRF(...) or FRF.from_control) gets the schema's required keys with neutral values."""
    _write_atomic(path, frf_to_doc(frf))


def read_model(path: PathLike) -> Model:
    """Read an msid-model/1 file (docs/model-format.md) into a Model."""
    return Model(_load(path, MODEL_FORMAT), path)


def write_model(path: PathLike, model: Model) -> None:
    """Write a Model as msid-model/1 (its doc, with A..D from the arrays)."""
    _write_atomic(path, model_to_doc(model))
