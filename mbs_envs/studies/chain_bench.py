"""The chain algorithms timed against the number of links, and against Pinocchio where it is installed (the logic of ``scripts/bench_chain.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

import json
import pathlib
import numpy as np
from tqdm import tqdm
from ..models import SerialChain
from ..models.spatial_chain import SpatialChain
from .benchmarking import median_time, pinocchio_chain, pinocchio_spatial_chain
from .plotting import pyplot, save


SIZES = [2, 5, 10, 20, 50, 100, 200, 500]


BATCH = 256


def run(out: pathlib.Path, sizes: list[int]) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    rows = []
    for n in tqdm(sizes, desc="chain sizes"):
        chain = SerialChain(n_links=n)
        q, v, u = (rng.uniform(-1, 1, n) for _ in range(3))
        Q, V, U = (rng.uniform(-1, 1, (BATCH, n)) for _ in range(3))
        row = {
            "n": n,
            "rnea_single": median_time(lambda: chain.rnea(q, v, u)),
            "aba_single": median_time(lambda: chain.aba(q, v, u)),
            "crba_cholesky_single": median_time(lambda: chain.forward_dynamics_crba(q, v, u)),
            "rnea_batch_per_env": median_time(lambda: chain.rnea(Q, V, U)) / BATCH,
            "aba_batch_per_env": median_time(lambda: chain.aba(Q, V, U)) / BATCH,
        }
        if n <= 200:  # O(N^3) per environment: skipped beyond
            row["crba_cholesky_batch_per_env"] = (
                median_time(lambda: chain.forward_dynamics_crba(Q, V, U), repeats=3) / BATCH
            )
        peer = pinocchio_chain(chain)
        if peer is not None:
            pin, model, data = peer
            row["pin_rnea_single"] = median_time(lambda: pin.rnea(model, data, q, v, u))
            row["pin_aba_single"] = median_time(lambda: pin.aba(model, data, q, v, u))
            a_pin = np.array(pin.aba(model, data, q, v, u))
            row["aba_agreement_rel"] = float(np.max(np.abs(chain.aba(q, v, u) - a_pin)) / np.max(np.abs(a_pin)))
        row.update(spatial_row(n, q, v, u, Q, V, U))
        rows.append(row)
    ns = np.array([r["n"] for r in rows], float)
    big = ns >= 20  # slopes on the asymptotic part (fixed per-call overheads dominate small N)
    slopes = {}
    for key in rows[0]:
        if key == "n" or key.endswith("agreement_rel"):
            continue
        y = np.array([r.get(key, np.nan) for r in rows])
        sel = big & np.isfinite(y)
        if sel.sum() >= 2:
            slopes[key] = float(np.polyfit(np.log(ns[sel]), np.log(y[sel]), 1)[0])
    result = {"batch": BATCH, "rows": rows, "loglog_slopes_n_ge_20": slopes, "pinocchio": "pin_aba_single" in rows[0]}
    (out / "bench_chain.json").write_text(json.dumps(result, indent=2))
    plot(rows, out / "bench_chain.png")
    print(
        f"{'N':>5} {'RNEA':>9} {'ABA':>9} {'CRBA+chol':>10} {'ABA/env@256':>12} {'pin aba':>9} {'ABA/pin':>8} {'ABA@256/pin':>12}   [us]"
    )
    for r in rows:
        pa = r.get("pin_aba_single")
        ratio = f"{r['aba_single'] / pa:8.2f}" if pa else "       -"
        ratio_b = f"{r['aba_batch_per_env'] / pa:12.2f}" if pa else "           -"
        pin_t = f"{pa * 1e6:9.1f}" if pa else "        -"
        print(
            f"{r['n']:5d} {r['rnea_single'] * 1e6:9.1f} {r['aba_single'] * 1e6:9.1f} "
            f"{r['crba_cholesky_single'] * 1e6:10.1f} {r['aba_batch_per_env'] * 1e6:12.2f} {pin_t} {ratio} {ratio_b}"
        )
    print("\nthe spatial chain (alternating axes; per call, and per member of a batch of 256) [us]")
    print(
        f"{'N':>5} {'ABA':>9} {'pin':>9} {'ratio':>6} {'RNEA':>9} {'pin':>9} {'ratio':>6} {'CRBA':>9} {'pin':>9} {'ABA@256':>9} {'pin@256':>9} {'ratio':>6}"
    )
    for r in rows:

        def cell(key, width=9):
            x = r.get(key)
            return f"{x * 1e6:{width}.1f}" if x is not None else " " * (width - 1) + "-"

        def ratio(a, b):
            return f"{r[a] / r[b]:6.2f}" if r.get(b) else "     -"

        print(f"{r['n']:5d} {cell('spatial_aba_single')} {cell('pin_spatial_aba_single')} {ratio('spatial_aba_single', 'pin_spatial_aba_single')} "
              f"{cell('spatial_rnea_single')} {cell('pin_spatial_rnea_single')} {ratio('spatial_rnea_single', 'pin_spatial_rnea_single')} "
              f"{cell('spatial_crba_single')} {cell('pin_spatial_crba_single')} {cell('spatial_aba_batch_per_env')} "
              f"{cell('pin_spatial_aba_batch_per_env')} {ratio('spatial_aba_batch_per_env', 'pin_spatial_aba_batch_per_env')}")  # fmt: skip
    print("log-log slopes (N >= 20):", {k: round(s, 2) for k, s in slopes.items()})
    print(f"written to {out}/bench_chain.json and bench_chain.png")
    return result


def spatial_row(n: int, q, v, u, Q, V, U) -> dict:
    """The spatial chain's timings at ``N = n`` (and Pinocchio's on the same model, where installed)."""
    chain = SpatialChain(n_links=n)
    row = {
        "spatial_aba_single": median_time(lambda: chain.aba(q, v, u)),
        "spatial_rnea_single": median_time(lambda: chain.rnea(q, v, u)),
        "spatial_crba_single": median_time(lambda: chain.mass_matrix(q)),
        "spatial_aba_batch_per_env": median_time(lambda: chain.aba(Q, V, U)) / BATCH,
        "spatial_rnea_batch_per_env": median_time(lambda: chain.rnea(Q, V, U)) / BATCH,
    }
    peer = pinocchio_spatial_chain(chain)
    if peer is not None:
        pin, model, data = peer
        row["pin_spatial_aba_single"] = median_time(lambda: pin.aba(model, data, q, v, u))
        row["pin_spatial_rnea_single"] = median_time(lambda: pin.rnea(model, data, q, v, u))
        row["pin_spatial_crba_single"] = median_time(lambda: pin.crba(model, data, q))

        def pin_batch(f):
            return lambda: [f(model, data, Q[b], V[b], U[b]) for b in range(BATCH)]

        row["pin_spatial_aba_batch_per_env"] = median_time(pin_batch(pin.aba), repeats=3) / BATCH
        row["pin_spatial_rnea_batch_per_env"] = median_time(pin_batch(pin.rnea), repeats=3) / BATCH
        a_pin = np.array(pin.aba(model, data, q, v, u))
        row["spatial_aba_agreement_rel"] = float(
            np.max(np.abs(chain.aba(q, v, u) - a_pin)) / max(1.0, np.max(np.abs(a_pin)))
        )
    return row


def plot(rows: list[dict], path: pathlib.Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 5))
    ns = [r["n"] for r in rows]
    for key, style in [
        ("rnea_single", "o-"), ("aba_single", "s-"), ("crba_cholesky_single", "^-"),
        ("aba_batch_per_env", "s--"), ("pin_rnea_single", "o:"), ("pin_aba_single", "s:"),
        ("spatial_aba_single", "D-"), ("spatial_rnea_single", "v-"), ("spatial_aba_batch_per_env", "D--"),
        ("pin_spatial_aba_single", "D:"), ("pin_spatial_rnea_single", "v:"), ("pin_spatial_aba_batch_per_env", "x:"),
    ]:  # fmt: skip
        ys = [r.get(key, np.nan) * 1e6 for r in rows]
        if np.any(np.isfinite(ys)):
            ax.loglog(
                ns,
                ys,
                style,
                label=key.replace("aba", "ABA").replace("rnea", "RNEA") + ("" if "spatial" in key else " (planar)"),
            )
    ax.set_xlabel("links N")
    ax.set_ylabel("time per call (or per env in a batch of 256) [us]")
    ax.legend()
    save(fig, path)
