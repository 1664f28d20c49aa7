"""Independent peers of msid, for its tests and `msid bench`; not part of the user package.

NumPy (and SciPy, scikit-rf) implementations of the same jobs, written from the papers, not from
msid's C code: frf_peer (`msid frf`), lpm_peer (`msid frf --method lpm`), bench_*_peer and crest_peer
(the benchmark peers of `msid bench`), structures (the simulated structures of the fitting tests and
benches, with scikit-rf's vector fitting). See tools/peers/README.md.
"""
