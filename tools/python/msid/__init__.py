"""msid in Python.

In process, over the C++ libraries of the msid command line (the compiled module msid._msid, built by
the msid build or pip install ./tools/python): msid.frf (arrays -> FRF, the bits of `msid frf`),
msid.Measurement (samples pushed block by block), msid.measure (a device
over Modbus or CAN, as `msid measure`), msid.design / msid.read_design (msid-design/1),
msid.fit (FRF -> Model, the model of `msid fit`) and msid.validate / Model.validate (`msid validate`).

File access (NumPy only, no compiled module needed): read_frf / write_frf (msid-frf/1), read_model /
write_model (msid-model/1), FRF.to_control() / Model.to_control() (python-control FRD, StateSpace, TransferFunction) and back
(FRF.from_control, Model.from_control). Plots (matplotlib): msid.plot (python3 -m msid.plot) and the
HTML report msid.report (python3 -m msid.report OUTDIR). Exact regions: msid.regions. See docs/python.md.
"""
from .files import (FRF, Model, FormatError, frf_from_doc, frf_to_doc, read_frf, read_model, write_frf,  # noqa: F401
                    write_model)
# msid._msid is imported by these on their first call, so the file functions work without it
from .compute import (ConvergenceWarning, Design, Measurement, MeasurementInterrupted, Modes, NoteWarning,  # noqa: F401
                      Validation, design, export, fit, frf, import_frf, measure, modes, read_design, validate)

__version__ = "0.1.0"
__all__ = ["frf", "export", "Measurement", "measure", "MeasurementInterrupted", "Design", "design", "read_design", "fit", "import_frf", "validate", "Validation", "modes", "Modes",
           "NoteWarning",
           "ConvergenceWarning", "FRF", "Model", "FormatError", "frf_from_doc", "frf_to_doc", "read_frf", "read_model",
           "write_frf", "write_model",
           "plot", "report", "regions"]


def __getattr__(name):
    # msid.plot / msid.report import matplotlib only when used
    if name in ("plot", "report", "regions"):
        import importlib
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'msid' has no attribute '{name}'")
