"""Q3 (+Q4 check): causal on-line identification on simulated records.
Identifier = wavelet network (ridge neurons phi(a*u - b), Gaussian or Mexican hat) + bias
neuron (a=0 -> h=1), weights initialised by least squares on training records ("from
measured data"), then adapted on line by sequential DRLS with per-neuron forgetting and a
U guard; target d = block-denoised X, available B samples late.
Research shortcut: the identifier runs on D=8-sample group means (lambda_step = lambda^D);
the metric is still computed against every sample (exact decomposition).
Run: python3 scripts/research/online.py [quick]"""
import sys
import numpy as np
from scipy.signal import lfilter
from fogsim import simulate, denoise_blocks, COND, ma_causal, kf_rw, kf_gm_floor

B, D = 512, 8
MA_WIN_S = [2, 5, 10, 20, 50, 100, 200]
KF_QR = [1e-8, 1e-7, 3e-7, 1e-6, 3e-6, 1e-5, 1e-4]


def ema(x, tau_samples):
    a = 1.0 / tau_samples
    zi = (x[:, :1] * (1 - a))
    return lfilter([a], [1, -(1 - a)], x, axis=1, zi=zi)[0]


def make_set(seed, n, cond, dt=0.01, batch=10, baselines=True):
    rng = np.random.default_rng(seed)
    out = {k: [] for k in ["T", "th", "thd", "lev", "d", "tm", "tss", "b0", "vd", "n", "sw", "dfull_ss"]}
    base_sse = {}
    base_dsse = {}
    for i0 in range(0, n, batch):
        r = min(batch, n - i0)
        rec = simulate(rng, r, dt=dt, **COND[cond])
        x, tt = rec["x"], rec["t"]
        N = x.shape[1]
        d = denoise_blocks(x, B)
        tru = rec["b0"][:, None] + rec["drift"]
        G = N // D
        g = lambda a: a[:, :G * D].reshape(a.shape[0], G, D).mean(-1)
        thf = ema(rec["temp"], 2.0 / dt)                           # 2-s EMA of measured temperature
        M = int(10 / dt)
        thd = np.zeros_like(thf)
        thd[:, M:] = (thf[:, M:] - thf[:, :-M]) / 10.0 * 60.0      # degC/min over the last 10 s
        thd[:, :M] = (thf[:, :M] - thf[:, :1]) / np.maximum(tt[:M], 1.0) * 60.0
        lev = ma_causal(x, int(10 / dt))                           # 10-s level of raw X
        out["T"].append(np.broadcast_to(g(tt[None]), (r, G)))
        out["th"].append(g(thf)); out["thd"].append(g(thd)); out["lev"].append(g(lev))
        dg = g(np.nan_to_num(d, nan=np.nan))
        out["d"].append(dg)
        tm = g(tru)
        out["tm"].append(tm)
        out["tss"].append(((tru[:, :G * D].reshape(r, G, D) - tm[..., None]) ** 2).sum(-1).sum(-1))
        out["b0"].append(rec["b0"])
        dr = rec["drift"][:, :G * D]
        out["vd"].append(((dr - dr.mean(1, keepdims=True)) ** 2).sum(1))
        out["n"].append(np.full(r, G * D)); out["sw"].append(rec["sigma_w"])
        fin = np.isfinite(d)
        out["dfull_ss"].append(np.where(fin, d, 0) ** 2 @ np.ones(N))
        if baselines:
            ests = {}
            for w in MA_WIN_S:
                ests[f"MA raw X {w:3d} s"] = ma_causal(x, int(w / dt))
                md = np.full_like(x, np.nan)
                L = int(w / dt)
                dz = np.where(fin, d, 0.0)
                # mean of d over [k-B-L+1, k-B] (d of sample j is known at sample j+B)
                c = np.concatenate([np.zeros((r, 1)), np.cumsum(dz, 1)], 1)
                k = np.arange(N)
                hi = np.clip(k - B + 1, 0, N); lo = np.clip(k - B - L + 1, 0, N)
                cnt = np.maximum(hi - lo, 1)
                md = (c[:, hi] - c[:, lo]) / cnt
                md[:, k < B] = x[:, 0:1]        # nothing known yet: first sample
                ests[f"MA of d (lag B) {w:3d} s"] = md
            for qr in KF_QR:
                ests[f"KF random-walk q/r={qr:g}"] = kf_rw(x, qr)
            ests["perfect identifier y = truth"] = tru
            for name, y in ests.items():
                base_sse.setdefault(name, []).append(((y[:, :G * D] - tru[:, :G * D]) ** 2).sum(1))
                e = np.where(fin, y - d, 0.0)
                base_dsse.setdefault(name, []).append((e ** 2).sum(1))
        del rec, x, d, tru
    S = {k: np.concatenate(v) for k, v in out.items()}
    gps = 100 / D                                   # groups per second (research runs at 100 Hz)
    S["tr"] = S["lev"] - ma_causal(S["lev"], int(50 * gps) + 1)   # 10-s level minus its 50-s mean (trend)
    S["base_sse"] = {k: np.concatenate(v) for k, v in base_sse.items()}
    S["base_dsse"] = {k: np.concatenate(v) for k, v in base_dsse.items()}
    return S


def metrics_from_groups(S, yg):
    """e_truth (denominator: drift RMS about record mean) and e_rel from group-held outputs."""
    sse = (D * (yg - S["tm"]) ** 2).sum(1) + S["tss"]
    et = np.sqrt(sse.sum() / S["vd"].sum())
    return et


# ---------------------------------------------------------------- the identifier
class Net:
    def __init__(self, inputs, K, phi="gauss", links=()):
        self.inputs, self.K, self.phi, self.links = inputs, K, phi, list(links)
        self.nlin = len(self.links)

    def fit_norm(self, S):
        self.c, self.s = {}, {}
        for nm in self.inputs + self.links:
            lo, hi = np.percentile(S[nm], [1, 99])
            self.c[nm], self.s[nm] = (hi + lo) / 2, (hi - lo) / 2

    def feats(self, S, j=None):
        """h for all neurons; first column = bias neuron (a=0, b=0 -> phi(0)=1)."""
        cols = []
        for nm, K in zip(self.inputs, self.K):
            u = (S[nm] if j is None else S[nm][:, j]) - self.c[nm]
            u = u / self.s[nm]
            cen = np.linspace(-1, 1, K)
            a = (K - 1) / 2.0                      # dilation = 1/spacing
            z = a * u[..., None] - a * cen
            cols.append(np.exp(-z * z / 2) if self.phi == "gauss" else (1 - z * z) * np.exp(-z * z / 2))
        one = np.ones((S["d"].shape[0],) + ((S["d"].shape[1],) if j is None else ()) + (1,))
        lin = [(((S[nm] if j is None else S[nm][:, j]) - self.c[nm]) / self.s[nm])[..., None] for nm in self.links]
        return np.concatenate([one] + lin + cols, -1)

    def pretrain(self, S, ridge=1e-3):
        """Least squares on training records, per-record intercept removed (within estimator);
        then bias weight = mean residual."""
        Lh = 1 + self.nlin + sum(self.K)
        A = np.zeros((Lh - 1, Lh - 1)); bvec = np.zeros(Lh - 1)
        res_means = []
        H = self.feats(S)[..., 1:]
        m = np.isfinite(S["d"])
        for r in range(H.shape[0]):
            h, dd = H[r][m[r]], S["d"][r][m[r]]
            h = h - h.mean(0); dd = dd - dd.mean()
            A += h.T @ h; bvec += h.T @ dd
        n = m.sum()
        w = np.linalg.solve(A + ridge * n * np.eye(Lh - 1), bvec)
        net = np.einsum("rgl,l->rg", H, w)
        w0 = np.nanmean(S["d"] - net)
        self.w_init = np.r_[w0, w]
        return self.w_init


def run_online(net, S, lam_b, lam_n, U0_b, U0_n, umin=1e-9, umax=1.0, adapt_net=True, w_init=None):
    """Causal on-line run. At group step j: y_j = w.h_j (weights trained on data up to
    step j-lag), then one sequential-DRLS update with (h_{j-lag}, d_{j-lag})."""
    R, G = S["d"].shape
    lag = B // D
    Lh = 1 + net.nlin + sum(net.K)
    w = np.tile(net.w_init if w_init is None else w_init, (R, 1))
    lam = np.r_[lam_b ** D, np.full(Lh - 1, lam_n ** D)]
    U = np.tile(np.r_[U0_b, np.full(Lh - 1, U0_n)], (R, 1))
    H = net.feats(S)
    y = np.empty((R, G))
    upd = range(Lh) if adapt_net else range(1)
    for j in range(G):
        y[:, j] = np.einsum("rl,rl->r", w, H[:, j])
        jt = j - lag
        if jt < 0 or not np.isfinite(S["d"][0, jt]):
            continue
        h = H[:, jt]
        e = S["d"][:, jt] - np.einsum("rl,rl->r", w, h)
        for a in upd:
            ua = U[:, a] / lam[a]
            ua = ua / (1 + ua * h[:, a] ** 2)
            ua = np.clip(ua, umin, umax)
            U[:, a] = ua
            st = ua * h[:, a] * e
            w[:, a] += st
            e = e - h[:, a] * st
    return y


def report_baselines(S, title):
    den = S["vd"].sum()
    rows = []
    for name in S["base_sse"]:
        rows.append((np.sqrt(S["base_sse"][name].sum() / den), name,
                     np.sqrt(S["base_dsse"][name].sum() / S["dfull_ss"].sum())))
    print(f"  baselines ({title}): e_truth | e_rel | estimator")
    for et, name, er in rows:
        print(f"    {et:6.3f} | {er:6.3f} | {name}")
    best = min(r for r in rows if not r[1].startswith("perfect"))
    print(f"    best causal baseline: {best[1]}  e_truth={best[0]:.3f}")
    return best


if __name__ == "__main__":
    quick = len(sys.argv) > 1 and sys.argv[1] == "quick"
    ntr, nva = (8, 6) if quick else (12, 8)
    np.seterr(all="ignore")
    for cond in ["ecore", "gm17", "rw17"]:
        print(f"\n===== condition set {cond}: {ntr} training + {nva} validation records, 100 Hz, 1800 s, B={B}")
        Str = make_set(100, ntr, cond, baselines=False)
        Sva = make_set(200, nva, cond)
        best = report_baselines(Sva, "validation")
        if cond == "gm17":
            fl = np.sqrt(np.mean([kf_gm_floor(s, 0.01, 19.5, 300.0) ** 2 for s in Sva["sw"]]))
            print(f"    (optimal-KF floor at tau=300 s for these sigma_w: {fl/17:.3f})")
        configs = [
            # name, gaussian inputs, K per input, linear links, lambda_b, lambda_n
            ("bias neuron only (EMA of d, lag B)", [], [], [], 0.999, 0.99999),
            ("29 G(lev10) + bias  [X input low-passed, no link]", ["lev"], [29], [], 0.9999, 0.99999),
            ("REC: bias + link(lev10) + 14 G(trend) + 14 G(T)", ["tr", "T"], [14, 14], ["lev"], 0.9999, 0.99999),
        ]
        if cond == "ecore":
            configs.append(("REC+temp: bias + link(lev10) + 14 G(trend) + 14 G(dtheta)", ["tr", "thd"], [14, 14], ["lev"], 0.9999, 0.99999))
        print("  identifier (pretrained on training records by LS, then on-line sequential DRLS, U0_b=1, U0_n=1e-4, guard [1e-9,1]):")
        print("    e_truth fixed-init | e_truth on-line | config")
        for name, inp, K, links, lb, ln in configs:
            net = Net(inp, K, links=links)
            if inp or links:
                net.fit_norm(Str)
                net.pretrain(Str)
            else:
                net.c, net.s = {}, {}
                net.w_init = np.array([np.nanmean(Str["d"])])
            y0 = net.feats(Sva) @ net.w_init
            y = run_online(net, Sva, lb, ln, 1.0, 1e-4)
            print(f"    {metrics_from_groups(Sva, y0):9.3f} | {metrics_from_groups(Sva, y):9.3f} | {name} (lambda_b={lb})")
