"""FOG static-record simulator, block wavelet denoiser, metrics and causal baselines.

Shared library for the research scripts (run `python3 scripts/research/fogsim.py` for a
table of the simulated condition sets).  Units: rates in deg/h inside the simulator
(output also in deg/s), time in s, temperature in deg C.

Record model (all components summed, then quantised):
  X(k) = B0 + drift(k) + n(k),  quantised to q = 60/32768 deg/s (= 6.59 deg/h)
  n      : white rate noise (angle random walk), per-sample std sigma_w deg/h
  drift  : sum of the enabled slow components (all zero-mean-ish processes):
    gm     : first-order Gauss-Markov, std sigma_gm, correlation time tau_gm
    bi     : bias-instability (flicker) approximant = sum of 4 GM, tau 3/30/300/3000 s,
             each std sigma_bi/2 (total std sigma_bi)
    rrw    : rate random walk, K deg/h/sqrt(h) (starts at 0)
    thermal: c1*(theta-25) + c2*(theta-25)^2 + c3*dtheta/dt   (theta deg C, dtheta/dt deg C/min)
             theta(t) = amb0 + slope*t + A*sin(2 pi t/P + ph) + dTw*(1-exp(-t/tau_w))
  B0     : constant turn-on bias (+ earth-rate part), N(0, sigma_b0) deg/h
  temp_c : measured temperature = theta + N(0,0.02) quantised to 1/16 deg C
"""
import numpy as np
import pywt
from scipy.signal import lfilter

Q_DPS = 60.0 / 32768.0          # rate LSB, deg/s
DPH = 3600.0                     # deg/h per deg/s


def gm(rng, R, N, dt, tau, sigma):
    """Stationary first-order Gauss-Markov, shape (R,N); tau, sigma scalars or (R,) arrays."""
    tau = np.broadcast_to(np.asarray(tau, float), (R,))
    sigma = np.broadcast_to(np.asarray(sigma, float), (R,))
    out = np.empty((R, N))
    for r in range(R):
        phi = np.exp(-dt / tau[r])
        w = rng.standard_normal(N) * sigma[r] * np.sqrt(1 - phi * phi)
        w[0] = rng.standard_normal() * sigma[r]
        out[r] = lfilter([1.0], [1.0, -phi], w)
    return out


def simulate(rng, R, dt=0.01, dur=1800.0, sigma_w=(30, 90), sigma_b0=20.0,
             gm_sigma=0.0, gm_tau=300.0, bi_sigma=0.0, rrw=0.0, thermal=0.0,
             coef_jitter=0.1):
    """Simulate R records of one sample period.  Tuple arguments are U(lo,hi) ranges.
    thermal: scale of the thermal drift (1.0 = nominal gyro, see THERMAL).
    Returns dict with t, x (deg/h, quantised), drift (deg/h, truth without B0), b0,
    temp (measured), theta (true), sigma_w (per record)."""
    N = int(round(dur / dt))
    t = np.arange(N) * dt
    u = lambda v: (rng.uniform(*v, size=R) if isinstance(v, tuple) else np.full(R, float(v)))
    sw = u(sigma_w)
    drift = np.zeros((R, N))
    if np.any(u(gm_sigma) > 0):
        drift += gm(rng, R, N, dt, u(gm_tau), u(gm_sigma))
    bs = u(bi_sigma)
    if np.any(bs > 0):
        for tau in (3.0, 30.0, 300.0, 3000.0):
            drift += gm(rng, R, N, dt, tau, bs / 2)
    K = u(rrw)
    if np.any(K > 0):
        q = K / 60.0 * np.sqrt(dt)             # deg/h per step (K deg/h/sqrt(h) = K/60 deg/h/sqrt(s))
        drift += np.cumsum(rng.standard_normal((R, N)) * q[:, None], axis=1)
    th = u(thermal)
    # temperature profile (always simulated so a temperature channel exists)
    amb0 = rng.uniform(-10, 40, R)[:, None]
    slope = rng.uniform(-4, 4, R)[:, None] / 3600.0         # deg C per s
    A = rng.uniform(0, 3, R)[:, None]
    P = rng.uniform(900, 3600, R)[:, None]
    ph = rng.uniform(0, 2 * np.pi, R)[:, None]
    dTw = rng.uniform(4, 14, R)[:, None]
    tauw = rng.uniform(200, 900, R)[:, None]
    theta = amb0 + slope * t + A * np.sin(2 * np.pi * t / P + ph) + dTw * (1 - np.exp(-t / tauw))
    dtheta = (slope + A * 2 * np.pi / P * np.cos(2 * np.pi * t / P + ph)
              + dTw / tauw * np.exp(-t / tauw)) * 60.0          # deg C per min
    if np.any(th > 0):
        c1, c2, c3 = THERMAL
        j = lambda: 1 + coef_jitter * rng.standard_normal((R, 1))
        drift += th[:, None] * (c1 * j() * (theta - 25) + c2 * j() * (theta - 25) ** 2
                                + c3 * j() * dtheta)
    b0 = rng.standard_normal(R) * sigma_b0
    x = b0[:, None] + drift + rng.standard_normal((R, N)) * sw[:, None]
    x = np.round(x / DPH / Q_DPS) * Q_DPS * DPH                # E-Core rate quantisation
    temp = np.round((theta + 0.02 * rng.standard_normal((R, N))) * 16) / 16
    return dict(t=t, dt=dt, x=x, drift=drift, b0=b0, temp=temp, theta=theta, sigma_w=sw)


# nominal thermal coefficients: deg/h per degC, deg/h per degC^2, deg/h per (degC/min)
THERMAL = (1.0, 0.026, 48.0)

# ---------------------------------------------------------------- condition sets
COND = {
    # the earlier quick model: stochastic GM drift only, 17 deg/h RMS
    "gm17": dict(gm_sigma=19.5, gm_tau=(100.0, 600.0)),
    # E-Core-like: thermal (warm-up + ambient) drift dominant, bias instability 1-2 deg/h, RRW
    "ecore": dict(thermal=1.0, bi_sigma=(1.0, 2.0), rrw=(0.5, 1.5)),
    # stochastic-only, random walk with ~17 deg/h RMS about the record mean (K=59 deg/h/sqrt(h))
    "rw17": dict(rrw=59.0),
}


# ---------------------------------------------------------------- denoiser
def denoise_blocks(x, B=512, wavelet="db4", level=3):
    """Paper's denoiser, block-wise: db4, 3 levels, periodization, soft universal threshold
    mu = sigma*sqrt(2 ln B), sigma = median(|finest details != 0|)/0.6745.
    Samples after the last full block are left as NaN (no target yet)."""
    R, N = x.shape
    nb = N // B
    xb = x[:, :nb * B].reshape(R, nb, B)
    coeffs = pywt.wavedec(xb, wavelet, mode="periodization", level=level, axis=-1)
    fin = np.abs(coeffs[-1])
    fin_m = np.where(fin == 0, np.nan, fin)
    sig = np.nanmedian(fin_m, axis=-1, keepdims=True) / 0.6745
    sig = np.nan_to_num(sig)
    mu = sig * np.sqrt(2 * np.log(B))
    out = [coeffs[0]] + [np.sign(c) * np.maximum(np.abs(c) - mu, 0) for c in coeffs[1:]]
    d = np.full((R, N), np.nan)
    d[:, :nb * B] = pywt.waverec(out, wavelet, mode="periodization", axis=-1).reshape(R, nb * B)
    return d


# ---------------------------------------------------------------- metrics
def e_truth(y, rec, sl=slice(None)):
    """RMS(y - (B0+drift)) / RMS(drift about its record mean), pooled over records.
    The constant B0 must be identified too but does not inflate the denominator."""
    tru = rec["b0"][:, None] + rec["drift"]
    num = np.mean((y[:, sl] - tru[:, sl]) ** 2)
    dd = rec["drift"][:, sl]
    den = np.mean((dd - dd.mean(axis=1, keepdims=True)) ** 2)
    return np.sqrt(num / den)


def e_rel(y, d, sl=slice(None)):
    """RMS(y-d)/RMS(d) over samples with a target (paper-like, d includes B0)."""
    yy, dd = y[:, sl], d[:, sl]
    m = np.isfinite(dd)
    return np.sqrt(np.mean((yy[m] - dd[m]) ** 2) / np.mean(dd[m] ** 2))


# ---------------------------------------------------------------- causal baselines
def ma_causal(x, w):
    """Causal moving average of the last w samples (fewer at the start)."""
    c = np.cumsum(x, axis=1)
    out = np.empty_like(x)
    out[:, :w] = c[:, :w] / np.arange(1, w + 1)
    out[:, w:] = (c[:, w:] - c[:, :-w]) / w
    return out


def kf_rw(x, q_over_r, p0_over_r=1e4):
    """Scalar Kalman filter, random-walk bias, measurement = x. Gain sequence depends
    only on q/r and P0/r, so it is computed once; then the time-varying first-order filter.
    Returns the a-posteriori estimate at each k (uses x up to and including k)."""
    R, N = x.shape
    K = np.empty(N)
    p = p0_over_r
    for k in range(N):
        p = p + (q_over_r if k else 0.0)
        K[k] = p / (p + 1.0)
        p = p * (1 - K[k])
        if k > 50 and abs(K[k] - K[k - 1]) < 1e-12 * K[k]:
            K[k:] = K[k]
            break
    y = np.empty_like(x)
    kss = np.argmax(K == K[-1])
    s = np.zeros(R)
    for k in range(kss + 1):
        s = s + K[k] * (x[:, k] - s)
        y[:, k] = s
    if kss + 1 < N:
        Ks = K[-1]
        zi = ((1 - Ks) * s)[:, None]
        y[:, kss + 1:] = lfilter([Ks], [1, -(1 - Ks)], x[:, kss + 1:], axis=1, zi=zi)[0]
    return y


def kf_gm_floor(sigma_w, dt, sigma_d, tau):
    """Steady-state a-posteriori error std of the optimal KF for a GM drift (std sigma_d,
    correlation tau) observed in white noise of per-sample std sigma_w (discrete exact)."""
    phi = np.exp(-dt / tau)
    q = sigma_d ** 2 * (1 - phi ** 2)
    r = sigma_w ** 2
    p = sigma_d ** 2
    for _ in range(200000):
        pm = phi * phi * p + q
        pn = pm * r / (pm + r)
        if abs(pn - p) < 1e-12 * p:
            break
        p = pn
    return np.sqrt(pn)


if __name__ == "__main__":
    rng = np.random.default_rng(1)
    print("condition set | drift RMS about mean (deg/h) [min med max] | sigma_w | RMS(d-truth) deg/h | RMS(d)")
    for name, kw in COND.items():
        rec = simulate(rng, 12, **kw)
        dr = rec["drift"] - rec["drift"].mean(1, keepdims=True)
        rms = np.sqrt((dr ** 2).mean(1))
        d = denoise_blocks(rec["x"])
        tru = rec["b0"][:, None] + rec["drift"]
        m = np.isfinite(d)
        print(f"{name:7s} | {np.sqrt((rms**2).mean()):5.1f} [{rms.min():5.1f} {np.median(rms):5.1f} {rms.max():5.1f}]"
              f" | {rec['sigma_w'].mean():5.1f} | {np.sqrt(np.mean((d[m]-tru[m])**2)):5.1f}"
              f" | {np.sqrt(np.mean(d[m]**2)):5.1f}")
