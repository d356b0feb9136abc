"""Accuracy of the identification methods on synthetic truth: bias, RMSE, 95 % coverage.

Methods, all on the same records (the Haar wavelet variance is computed once per record; the
overlapping Allan variance is twice it, so the Allan methods get exactly allantools' curve):

    ieee   IEEE Std 952 slope read-offs (noise/readoffs.py ieee_readoffs): N on the
           -1/2 line at 1 s, K on the +1/2 line at 3 s, B = min ADEV / 0.664, T = tau at the
           minimum; intervals from the read point's 95 % Greenhall chi-square bounds
    allan  today's weighted least-squares fit of the composite Allan variance (noise/fit.py
           fit_curve, Greenhall-edf weights, every octave tau) with the truth's number of
           poles, and its widened Jacobian intervals
    gmwm   GMWM with the truth's model, iterated efficient weighting with the exact
           finite-record Omega (noise/gmwm.py), asymptotic intervals
    gmwm_boot  (with --bootstrap R) the same estimates with the parametric bootstrap's
           percentile intervals (gmwm.bootstrap, R records simulated from each fit)

Truths: "paper" (white + Gauss-Markov + random walk, the paper profile's N, B, T, K) and
"twopole" (white + two Gauss-Markov poles + random walk; the read-offs, which see one pole,
are scored on N and K only). Records are drawn directly with numpy (gmwm.simulate, the
generator's discretization) at 200 Hz, seed by seed; each finished record is appended to the
checkpoint file (JSON lines), so an interrupted run continues where it stopped.

    nice python tools/identification_accuracy.py                     # the full study
    python tools/identification_accuracy.py --seeds 20 --lengths 2.8 # a quick look
    python tools/identification_accuracy.py --table-only             # table from the checkpoint
    python tools/identification_accuracy.py --truths twopole --lengths 6 --seeds 20 \
        --bootstrap 100 --checkpoint boot.jsonl                       # bootstrap intervals too

Errors are relative to the truth (%); RMSE is dominated by the few records where a term is
not resolved (a slow pole taken for a random walk), the median absolute error is not.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from bmg160_emu.noise import gmwm
from bmg160_emu.noise.allan import allan_confidence, noise_alpha_from_slope
from bmg160_emu.noise.fit import FitError, fit_curve
from bmg160_emu.noise.profile import load_profile
from bmg160_emu.noise.readoffs import ieee_readoffs
from bmg160_emu.noise.wavelet import MIN_COEFFS_FRACTION, haar_wv

RATE_HZ = 200.0
_PAPER = load_profile("paper").x
TRUTHS = {
    "paper": (("WN", "GM", "RW"), {"N": _PAPER.N, "B": _PAPER.B, "T": _PAPER.T, "K": _PAPER.K}),
    # two poles a factor 30 apart under the paper's white and random-walk levels; each peaks
    # (AVAR 0.38 B^2 at tau = 2 T) at about a tenth (T1) and the same level (T2) as the rest
    "twopole": (
        ("WN", "GM", "GM", "RW"),
        {"N": _PAPER.N, "B1": 4.0e-3, "T1": 2.0, "B2": 4.0e-3, "T2": 60.0, "K": _PAPER.K},
    ),
}
METHODS = ("ieee", "allan", "gmwm")


def one_record(truth: str, hours: float, seed: int, bootstrap: int = 0) -> dict:
    model, params = TRUTHS[truth]
    n = round(hours * 3600 * RATE_HZ)
    # one independent stream per (truth, length, seed)
    key = [seed, round(hours * 100), list(TRUTHS).index(truth)]
    rng = np.random.default_rng(np.random.SeedSequence(key))
    x = gmwm.simulate(model, list(params.values()), n, RATE_HZ, rng)
    wv = haar_wv(x, RATE_HZ)
    out: dict = {"truth": truth, "hours": hours, "seed": seed}
    adev = np.sqrt(wv.avar)
    alphas = noise_alpha_from_slope(wv.taus_s, adev)
    curve = allan_confidence(wv.taus_s, adev, wv.n_coeffs, alphas, n, RATE_HZ, 0.683)
    out["ieee"] = _ieee(curve, n)
    out["allan"] = _allan(curve, n, model.count("GM"))
    n_min = MIN_COEFFS_FRACTION * n
    fit = gmwm.gmwm_fit(wv.up_to(int((n + 1 - n_min) // 2)), model)
    out["gmwm"] = {k: [e.value, e.ci_low, e.ci_high] for k, e in fit.estimates.items()}
    if bootstrap:  # the same fit, scored on its parametric-bootstrap percentile intervals
        gmwm.bootstrap(fit, bootstrap, seed=int(rng.integers(2**63)))
        out["gmwm_boot"] = {k: [e.value, e.boot_low, e.boot_high]
                            for k, e in fit.estimates.items()}
        out["bootstrap_replicates"] = bootstrap
    return out


def _allan(curve, n: int, poles: int) -> dict:
    """Today's fit (fit.fit_curve) with the truth's number of poles, as GMWM gets the truth's
    model; several poles are numbered in T order like GMWM's."""
    try:
        fit = fit_curve(curve, RATE_HZ, n, poles=poles)
    except FitError:
        return {}
    out = {k: [e.value, e.ci_low, e.ci_high] for k, e in (("N", fit.N), ("K", fit.K))}
    for i, term in enumerate(fit.terms, start=1):
        suffix = str(i) if poles > 1 else ""
        for name, e in (("B", term.B), ("T", term.T)):
            out[name + suffix] = [e.value, e.ci_low, e.ci_high]
    return out


def _ieee(curve, n: int) -> dict:
    ro = ieee_readoffs(curve)
    adev = curve.adev
    ci95 = allan_confidence(
        curve.taus, adev, curve.n_terms, noise_alpha_from_slope(curve.taus, adev), n, RATE_HZ, 0.95
    )
    out: dict = {}

    def rel_ci(tau: float | None) -> tuple[float, float]:
        if tau is None:
            return math.nan, math.nan
        i = int(np.argmin(np.abs(np.log(curve.taus / tau))))
        return ci95.ci_low[i] / adev[i], ci95.ci_high[i] / adev[i]

    for name, key, tau_key in (
        ("N", "N_at_tau_1s", "line_through_tau_s"),
        ("K", "K_at_tau_3s", "line_through_tau_s"),
        ("B", "B_flicker", "tau_s"),
    ):
        value = ro[key]["value"]
        if value is None:
            continue
        lo, hi = rel_ci(ro[key].get(tau_key))
        out[name] = [value, value * lo, value * hi]
    out["T"] = [ro["tau_at_minimum"]["value"], math.nan, math.nan]
    return out


def run(args) -> None:
    path = Path(args.checkpoint)
    done = set()
    if path.exists():
        for line in path.read_text().splitlines():
            r = json.loads(line)
            done.add((r["truth"], r["hours"], r["seed"]))
    start = time.perf_counter()
    with path.open("a") as fh:
        for truth in args.truths:
            for hours in args.lengths:
                for seed in range(args.first_seed, args.seeds):
                    if (truth, hours, seed) in done:
                        continue
                    r = one_record(truth, hours, seed, args.bootstrap)
                    fh.write(json.dumps(r) + "\n")
                    fh.flush()
    print(f"computed in {time.perf_counter() - start:.0f} s (records already done were skipped)")


def table(path: Path, seeds: int, lengths, truths) -> str:
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    lines = [
        (
            "| truth | length | parameter | method | bias % | RMSE % | median abs. error % "
            "| 95 % coverage | records |"
        ),
        "| --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    methods = METHODS + (("gmwm_boot",) if any("gmwm_boot" in r for r in rows) else ())
    for truth in truths:
        _, params = TRUTHS[truth]
        for hours in lengths:
            sel = [r for r in rows if r["truth"] == truth and r["hours"] == hours]
            sel = [r for r in sel if r["seed"] < seeds]
            if not sel:
                continue
            for name, true in params.items():
                for method in methods:
                    vals = [r[method][name] for r in sel if name in r.get(method, {})]
                    if not vals:
                        continue
                    v = np.array(vals, dtype=float)
                    ok = np.isfinite(v[:, 0])
                    err = v[ok, 0] / true - 1.0
                    bias, rmse = 100 * err.mean(), 100 * math.sqrt(float(np.mean(err**2)))
                    mae = 100 * float(np.median(np.abs(err)))
                    has_ci = np.isfinite(v[ok, 1]) | np.isfinite(v[ok, 2])
                    if has_ci.any():
                        lo = np.where(np.isnan(v[ok, 1]), -np.inf, v[ok, 1])
                        hi = np.where(np.isnan(v[ok, 2]), np.inf, v[ok, 2])
                        cov = f"{100 * np.mean((lo <= true) & (true <= hi)):.1f} %"
                    else:
                        cov = "none"
                    missing = len(sel) - int(ok.sum())
                    count = f"{int(ok.sum())}" + (f" ({missing} not found)" if missing else "")
                    lines.append(
                        f"| {truth} | {hours:g} h | {name} | {method} | {bias:+.1f} | "
                        f"{rmse:.1f} | {mae:.1f} | {cov} | {count} |"
                    )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=200, help="records per case (default 200)")
    parser.add_argument(
        "--lengths",
        type=float,
        nargs="+",
        default=[2.8, 6.0, 24.0],
        help="hours (default 2.8 6 24)",
    )
    parser.add_argument(
        "--truths", nargs="+", choices=list(TRUTHS), default=list(TRUTHS), help="truth models"
    )
    parser.add_argument(
        "--checkpoint",
        default="identification_accuracy.jsonl",
        help="JSON-lines results file, appended record by record (default %(default)s)",
    )
    parser.add_argument("--first-seed", type=int, default=0,
                        help="first seed to compute (two processes can share the seeds)")
    parser.add_argument("--bootstrap", type=int, default=0, metavar="R",
                        help="also score GMWM's parametric-bootstrap intervals (R replicates "
                        "per record; method gmwm_boot)")
    parser.add_argument("--table-only", action="store_true", help="only print the table")
    args = parser.parse_args()
    if not args.table_only:
        run(args)
    print(table(Path(args.checkpoint), args.seeds, args.lengths, args.truths))


if __name__ == "__main__":
    main()
