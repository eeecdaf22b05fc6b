"""Q4: theoretical floor of e_truth for ANY causal estimator (optimal steady-state Kalman
filter with known model) vs white-noise level and drift type / bandwidth.
e_floor = sqrt(P_ss) / RMS(drift about its 1800-s record mean), fixed at 17 deg/h.
Run: python3 scripts/research/floor.py"""
import numpy as np
from fogsim import kf_gm_floor

T, DT, RMS_IN = 1800.0, 0.01, 17.0


def gm_sigma_for_in_record_rms(tau, rms=RMS_IN, T=T):
    # var of the record mean of a stationary GM over [0,T]
    a = T / tau
    vm = 2.0 / a * (1 - (1 - np.exp(-a)) / a)
    return rms / np.sqrt(1 - vm)


print("Optimal causal (Kalman, known model) floor of e_truth, 100 Hz, drift RMS about record mean = 17 deg/h")
print("GM drift: rows = correlation time tau (s), columns = white noise per sample (deg/h)")
sws = [30, 45, 60, 90]
print("tau_s   sigma_gm | " + " ".join(f"{s:>7d}" for s in sws))
for tau in [30, 100, 300, 1000, 3000, 10000, 30000]:
    sg = gm_sigma_for_in_record_rms(tau)
    row = [kf_gm_floor(s, DT, sg, tau) / RMS_IN for s in sws]
    print(f"{tau:6.0f}  {sg:7.1f}  | " + " ".join(f"{v:7.3f}" for v in row))

print("\nRandom-walk drift (RRW) with 17 deg/h RMS about the record mean: K = 17/sqrt(T/6) per sqrt(s)")
K = RMS_IN / np.sqrt(T / 6)
for s in sws:
    q, r = K * K * DT, s * s
    p = (-q + np.sqrt(q * q + 4 * q * r)) / 2          # a-posteriori steady state
    print(f"  sigma_w={s:3d} deg/h: K={K*60:5.1f} deg/h/sqrt(h)  floor e_truth = {np.sqrt(p)/RMS_IN:6.3f}")

print("\nLargest white noise (deg/h per sample, 100 Hz) for which the floor is <= 0.10 (GM drift):")
for tau in [100, 300, 1000, 3000, 10000]:
    sg = gm_sigma_for_in_record_rms(tau)
    lo, hi = 1.0, 500.0
    for _ in range(40):
        mid = np.sqrt(lo * hi)
        if kf_gm_floor(mid, DT, sg, tau) / RMS_IN <= 0.10:
            lo = mid
        else:
            hi = mid
    print(f"  tau={tau:6d} s: sigma_w <= {lo:6.1f} deg/h  (ARW {lo*np.sqrt(DT)/60:.3f} deg/sqrt(h))")

print("\nE-Core-like stochastic residue (what no temperature model can explain): bias-instability")
print("approximant (4 GM, tau 3/30/300/3000 s, each sigma_bi/2) + RRW K deg/h/sqrt(h); exact joint")
print("5-state Kalman floor (DARE), relative to 17 deg/h:")
from scipy.linalg import solve_discrete_are
for sbi in [1.0, 2.0]:
    for Kh in [1.0]:
        for s in [30, 60, 90]:
            taus = (3.0, 30.0, 300.0, 3000.0)
            A = np.diag([np.exp(-DT / t) for t in taus] + [1.0])
            Q = np.diag([(sbi / 2) ** 2 * (1 - np.exp(-2 * DT / t)) for t in taus] + [(Kh / 60) ** 2 * DT])
            H = np.ones((1, 5))
            P = solve_discrete_are(A.T, H.T, Q, np.array([[s * s]]))
            Pp = P - P @ H.T @ H @ P / (H @ P @ H.T + s * s)
            e = np.sqrt((H @ Pp @ H.T)[0, 0])
            print(f"  sigma_bi={sbi:.0f}, K={Kh:.0f}, sigma_w={s:2d}: residue floor {e:5.2f} deg/h = {e/RMS_IN:5.3f} of 17 deg/h")
