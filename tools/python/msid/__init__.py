"""msid in Python, by concept (docs/python.md):

- Estimating an FRF (msid.compute, the compiled module msid._msid): msid.frf (periodic records, as
  `msid frf`), msid.lpm and msid.etfe (records of any input, `msid frf --method lpm|etfe`),
  msid.Measurement (samples pushed block by block), msid.measure (a device over Modbus or CAN, as
  `msid measure`); excitation designs msid.design / msid.read_design (msid-design/1).
- Fitting and checking a model (compiled): msid.fit (FRF or records -> Model, as `msid fit`),
  msid.validate / Model.validate (`msid validate`), msid.modes / Model.modes (`msid modes`).
- The data types (msid.types, NumPy only): FRF, Model, Validation, Modes, FormatError; python-control
  conversion FRF.to_control() / Model.to_control() and back (FRF.from_control, Model.from_control).
- Files (msid.files): read_frf / write_frf (msid-frf/1) and read_model / write_model (msid-model/1) need
  NumPy only. The FRF files of other tools (Touchstone .sNp, UFF .uff/.unv, CSV, MATLAB .mat) are read
  by msid.import_frf, and by read_frf for those extensions, through the compiled module's readers;
  msid.export (.csv, .mat for other tools) writes through it too.
- Plots (matplotlib): msid.plot (python3 -m msid.plot), the HTML report msid.report (python3 -m
  msid.report OUTDIR); exact confidence regions: msid.regions.

The compiled module is imported on the first call that needs it: the rest works without it.
"""
from .compute import (ConvergenceWarning, Design, Measurement, MeasurementInterrupted, NoteWarning, design,
                      etfe, export, fit, frf, lpm, measure, read_design)
from .files import import_frf, read_frf, read_model, write_frf, write_model
from .types import FRF, FormatError, Model, Modes, Validation, modes, validate

__version__ = "0.1.0"
__all__ = [
    # estimating an FRF
    "frf", "lpm", "etfe", "Measurement", "measure", "MeasurementInterrupted", "NoteWarning",
    "Design", "design", "read_design",
    # fitting and checking a model
    "fit", "ConvergenceWarning", "validate", "Validation", "modes", "Modes",
    # the data types
    "FRF", "Model", "FormatError",
    # files
    "read_frf", "write_frf", "read_model", "write_model", "import_frf", "export",
    # plots and regions (imported on first use)
    "plot", "report", "regions",
]


def __getattr__(name: str):
    # msid.plot / msid.report import matplotlib only when used
    if name in ("plot", "report", "regions"):
        import importlib
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'msid' has no attribute '{name}'")
