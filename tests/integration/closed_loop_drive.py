"""A simulated closed-loop drive, as a drive's logger writes it: `t,r1,u1,y1` (time, position reference,
motor voltage, measured position) at 1 kHz. The plant is a prismatic joint driven by a DC motor (mass and
viscous friction, position per voltage gtau / (s (M s + Fv)), sampled with a zero-order hold) under a PD
position controller; the reference is a periodic multisine of positions rolling off above F0. Two noises
enter inside the loop: a force disturbance d at the plant's input (friction and cogging) and the encoder's
noise n on the measured position, which the controller feeds back into u:

    u = C S r - T d - C S n,    y_measured = G C S r + G S d + S n,    S = 1 / (1 + G C), T = G C S.

The controller shapes the plant's input: at low frequencies the loop follows r with little voltage (G
integrates) while the disturbance reaches u through T ~ 1; at high frequencies the reference rolls off
and the encoder noise reaches u through C S ~ C. So some lines of the reference carry little plant input.
The record is in steady state (a period of warm-up is simulated and dropped). Used by
test_frf_closed_loop.py."""
import numpy as np
from scipy import signal

FS = 1000.0
M, FV, GTAU = 95.1, 203.5, 35.15       # kg, N s/m, N/V
KP, KD, TF = 2000.0, 60.0, 0.002        # V/m, V s/m, s: C(s) = KP + KD s / (TF s + 1)
F0 = 3.0                                # Hz: the reference's roll-off
# the reference's amplitude per line below F0 (m), the disturbance at the plant's input (V per sample: a
# force as the voltage that gives it) and the encoder noise (m per sample)
AMP, SD_D, SD_N = 1e-3, 1.0, 2e-5


def plant():
    """G(z) = B/A (descending powers of z, equal lengths) of the ZOH-sampled plant."""
    b, a, _ = signal.cont2discrete(([GTAU], [M, FV, 0.0]), 1 / FS, method="zoh")
    return b.ravel(), np.asarray(a, float)


def controller():
    """C(z) = Nc/Dc (Tustin)."""
    return signal.bilinear([KD + KP * TF, KP], [TF, 1.0], FS)


def plant_frf(bins, P):
    """The plant's FRF (position per voltage) at the bins of period P."""
    b, a = plant()
    z = np.exp(2j * np.pi * np.asarray(bins, float) / P)
    return np.polyval(b, z) / np.polyval(a, z)


def _mul(p, q):
    """p q of two polynomials in z (descending powers), leading zeros kept: every product below has the
    same length, so each ratio read in powers of z^-1 (lfilter) is the same transfer function (NumPy's
    polymul drops the plant numerator's leading zero, which would advance the output one sample)."""
    return np.convolve(p, q)


def _loop():
    b, a = plant()
    nc, dc = controller()
    acl = _mul(a, dc) + _mul(b, nc)
    return b, a, nc, dc, acl


def input_snr_db(bins, P, K, amp=AMP, sd_d=SD_D, sd_n=SD_N):
    """The SNR of the plant input's period mean over K periods at the bins (dB): the periodic part of u
    against the noise the loop puts into it, from the transfer functions (what the FRF's excitation test
    estimates from the record)."""
    b, a, nc, dc, acl = _loop()
    z = np.exp(2j * np.pi * np.asarray(bins, float) / P)
    cs = np.polyval(_mul(nc, a), z) / np.polyval(acl, z)
    t = np.polyval(_mul(b, nc), z) / np.polyval(acl, z)
    f = np.asarray(bins, float) * FS / P
    r = amp * P / 2 / (1 + (f / F0) ** 2)
    return 10 * np.log10(np.abs(cs * r) ** 2 * K / (P * (np.abs(t) ** 2 * sd_d ** 2 + np.abs(cs) ** 2 * sd_n ** 2)))


def drive(path, P, K, bins, seed, amp=AMP, sd_d=SD_D, sd_n=SD_N):
    """Writes the record (K periods of P samples, the reference on `bins` with random phases) to `path`."""
    rng = np.random.default_rng(seed)
    b, a, nc, dc, acl = _loop()
    f = np.asarray(bins, float) * FS / P
    R = np.zeros(P // 2 + 1, complex)
    R[bins] = amp * P / 2 / (1 + (f / F0) ** 2) * np.exp(2j * np.pi * rng.random(len(bins)))
    n = (K + 1) * P
    r = np.tile(np.fft.irfft(R, P), K + 1)
    d = sd_d * rng.standard_normal(n)
    e = sd_n * rng.standard_normal(n)
    lf = lambda num, x: signal.lfilter(num, acl, x)
    u = lf(_mul(nc, a), r) - lf(_mul(b, nc), d) - lf(_mul(nc, a), e)
    y = lf(_mul(b, nc), r) + lf(_mul(b, dc), d) + lf(_mul(a, dc), e)
    t = np.arange(K * P) / FS
    cols = np.column_stack([t, r[P:], u[P:], y[P:]])
    np.savetxt(path, cols, delimiter=",", header="t,r1,u1,y1", comments="", fmt="%.12g")
    return path
