"""Python side of msid: an independent NumPy peer of `msid frf` (frf_peer) and
the NumPy peer used by `msid bench frf` (bench_peer, also run as a script)."""
