"""Q1 + Q2: the faithful port (inputs X and T, L=30, lambda=0.63, eq. 15) on simulated
E-Core-like records; why it fails, quantified.
Run: python3 scripts/research/faithful.py      (about 1 min)"""
import numpy as np
from fogsim import simulate, denoise_blocks, COND, ma_causal, e_truth

L, LAM = 30, 0.63


def xt_features(x, t, cx, sx, T=1800.0, phi="gauss"):
    """15 ridge neurons on normalised X, 15 on normalised T (additive WNN).
    u = (X-cx)/sx, v = 2T/T_rec-1; centres c_i evenly in [-1,1]; a = 7 (spacing = 1/a);
    h = phi(a*u - a*c_i)."""
    u = (x - cx[:, None]) / sx[:, None]
    v = 2 * t / T - 1
    c = np.linspace(-1, 1, 15)
    a = 7.0
    z = np.concatenate([a * u[..., None] - a * c, np.broadcast_to(a * v[None, :, None] - a * c, u.shape + (15,))], axis=-1)
    return np.exp(-z * z / 2) if phi == "gauss" else (1 - z * z) * np.exp(-z * z / 2)


def drls(H, d, lam, U0, mode, umin=None, umax=None):
    """Per-weight RLS of eq. (15). H (R,N,L), d (R,N). mode 'parallel' (same a-priori error
    for all weights, as eq. 15 is written) or 'sequential' (error refreshed after each
    weight).  Returns a-priori errors, outputs, loop gain sum_a U_a h_a^2, divergence index."""
    R, N, Ln = H.shape
    w = np.zeros((R, Ln))
    U = np.full((R, Ln), float(U0))
    ep = np.full((R, N), np.nan)
    gain = np.full((R, N), np.nan)
    div = np.full(R, -1)
    scale = np.sqrt(np.nanmean(d ** 2, axis=1))
    for k in range(N):
        h = H[:, k, :]
        e = d[:, k] - np.sum(w * h, axis=1)
        ep[:, k] = e
        if mode == "parallel":
            U = U / lam / (1 + U / lam * h * h)
            if umax is not None:
                U = np.clip(U, umin, umax)
            w = w + U * h * e[:, None]
            gain[:, k] = np.sum(U * h * h, axis=1)
        else:
            g = 0.0
            for a in range(Ln):
                ua = U[:, a] / lam
                ua = ua / (1 + ua * h[:, a] ** 2)
                if umax is not None:
                    ua = np.clip(ua, umin, umax)
                U[:, a] = ua
                step = ua * h[:, a] * e
                w[:, a] += step
                e = e - h[:, a] * step
                g = g + ua * h[:, a] ** 2
            gain[:, k] = g
        bad = (~np.isfinite(e) | (np.abs(e) > 1e3 * scale)) & (div < 0)
        div[bad] = k
        if np.all(div >= 0):
            break
    return ep, gain, div


if __name__ == "__main__":
    rng = np.random.default_rng(2007)
    R = 6
    rec = simulate(rng, R, **COND["gm17"])
    x, t = rec["x"], rec["t"]
    d = denoise_blocks(x)
    N = x.shape[1]
    tru = rec["b0"][:, None] + rec["drift"]
    cx, sx = x.mean(1), 3 * x.std(1)
    H = xt_features(x, t, cx, sx)
    np.seterr(all="ignore")

    print("== Q1a  eq. (15) parallel (as written), lambda=0.63, L=30 (X,T), gm17 set, 6 records")
    print("U_a(0) | divergence sample per record (|e| > 1000 RMS(d) or non-finite) | median loop gain sum U h^2 before")
    for U0 in [1e-3, 1.0, 1e3]:
        ep, gain, div = drls(H[:, :4000], d[:, :4000], LAM, U0, "parallel")
        g = np.nanmedian(gain[:, 5:200])
        print(f"{U0:7g} | {[int(v) for v in div]} | {g:5.2f}")
    # which neurons are active: number with h > 0.1 per sample
    act = np.mean(np.sum(H[:, :4000] > 0.1, axis=2))
    print(f"mean number of neurons with h>0.1 per sample: {act:.1f}; stationary per-neuron U h^2 ~ (1-lambda)={1-LAM:.2f}")
    print("(parallel update multiplies the a-posteriori error by (1 - sum U h^2); stable only if sum < 2)")
    for lam in [0.9, 0.99, 0.999]:
        ep, gain, div = drls(H[:, :4000], d[:, :4000], lam, 1.0, "parallel")
        print(f"  parallel lambda={lam}: divergence samples {[int(v) for v in div]}  median loop gain {np.nanmedian(gain[:, 200:]):.2f}")

    print("\n== Q1b  sequential DRLS (error refreshed after each weight), guard U in [1e-6, Umax], U0=1, first 300 s")
    n6 = 30000
    for lam, umax in [(0.63, 1e2), (0.63, 1.0), (0.9999, 1.0)]:
        ep, gain, div = drls(H[:, :n6], d[:, :n6], lam, 1.0, "sequential", 1e-6, umax)
        print(f"Umax={umax:g} divergence samples {[int(v) for v in div]}", end="  ")
        y = d[:, :n6] - ep
        m = np.isfinite(ep) & np.isfinite(d[:, :n6])
        print(f"lambda={lam:7g}: finite={np.all(div < 0)}  RMS(a-priori e)/RMS(d)={np.sqrt(np.mean(ep[m]**2)/np.mean(d[:, :n6][m]**2)):.3f}"
              f"  e_truth(y=d-e)={e_truth(y, {**rec, 'drift': rec['drift'][:, :n6]}, slice(None)):.3f}")

    print("\n== Q1c  batch least squares of the (X,T) network, in-sample (best possible weights), target d")
    m = np.isfinite(d)
    res = {}
    for name, cols in [("X+T (30)", slice(0, 30)), ("X only (15)", slice(0, 15)), ("T only (15)", slice(15, 30))]:
        ys = np.empty_like(x)
        W = []
        for r in range(R):
            A = np.c_[H[r][:, cols], np.ones(N)]
            w_, *_ = np.linalg.lstsq(A[m[r]], d[r][m[r]], rcond=None)
            ys[r] = A @ w_
            W.append(w_)
        res[name] = (ys, W)
        print(f"{name:12s} (+bias): e_truth = {e_truth(ys, rec):.3f}   RMS(y-d)/RMS(d) = {np.sqrt(np.nanmean((ys-d)**2)/np.nanmean(d**2)):.3f}")
    # T-only weights of record r applied to record r+1 (T is not transferable)
    ys, W = res["T only (15)"]
    yx = np.empty_like(x)
    for r in range(R):
        A = np.c_[H[(r + 1) % R][:, 15:30], np.ones(N)]
        yx[(r + 1) % R] = A @ W[r]
    print(f"T-only weights of another record: e_truth = {e_truth(yx, rec):.3f}")
    for wsec in [1, 10, 60]:
        print(f"causal moving average {wsec:3d} s of X: e_truth = {e_truth(ma_causal(x, int(wsec*100)), rec):.3f}")

    print("\n== Q2  reasons, quantified")
    sw = rec["sigma_w"]
    vd = np.mean((rec["drift"] - rec["drift"].mean(1, keepdims=True)) ** 2, axis=1)
    nd = np.sqrt(np.nanmean((d - tru) ** 2, axis=1))
    print("(a) X carries the noise. per record: sigma_w | RMS(d - truth) | drift RMS | linear-regression slope beta=cov(d,X)/var(X)"
          " | predicted e_truth of y=beta*X")
    for r in range(R):
        xr = x[r] - x[r].mean()
        dr = d[r][m[r]] - d[r][m[r]].mean()
        beta = np.dot(xr[m[r]], dr) / np.dot(xr[m[r]], xr[m[r]])
        e_pred = np.sqrt(((1 - beta) ** 2 * vd[r] + beta ** 2 * sw[r] ** 2) / vd[r])
        print(f"    {sw[r]:5.1f} | {nd[r]:5.1f} | {np.sqrt(vd[r]):5.1f} | {beta:5.3f} | {e_pred:5.2f}")
    print("    -> d keeps the in-band part of the noise of X (~sigma_w/sqrt(8) after 3 levels), which is correlated")
    print("       with X itself, so f(X) is pulled towards the identity and passes beta*sigma_w of white noise to y.")
    print("(b) T is absolute: in-sample the T-neurons are a non-causal 15-knot smoother of this record (good fit),")
    print("    but the same T-weights on another record give the e_truth above; on line a T-neuron only")
    print(f"    sees data while it is active (~{1800/14:.0f} s window once per record), so it cannot generalise.")
    for lam in [0.63, 0.9, 0.99, 0.999, 0.9999]:
        print(f"(c) lambda={lam:7g}: memory 1/(1-lambda) = {1/(1-lam):8.1f} samples; white-noise std factor of an"
              f" exponential average sqrt((1-l)/(1+l)) = {np.sqrt((1-lam)/(1+lam)):.3f}")
