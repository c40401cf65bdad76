#!/usr/bin/env python3
"""Equal-CPU budgets of the peer comparison (`compare_cycles.py`), kept apart from it so
that they need nothing beyond the standard library and can be checked on their own:
`python3 scripts/budget.py` runs the self-test (the test suite does, tests/bench.rs).

Model. A render's process CPU time is t(n) = o + c * n for n samples per pixel: a fixed
cost o (loading, film, output) and a cost c per sample. `cpu_model` fits c by least squares
through the 1-spp point, c = sum((n - 1)(t_n - t_1)) / sum((n - 1)^2), and o = t_1 - c; a
rung of n spp then costs c * n.

Error at a budget. `at_budget` interpolates a renderer's error between the two rungs whose
CPU times bracket the budget, linearly in (log CPU, log error): the convergence rate
measured there, which for Owen-scrambled Sobol points at a few samples per pixel is far
from 1/sqrt(time). Outside the ladder the nearest end is scaled by sqrt(cpu / budget).
"""

import math


def cpu_model(least):
    """`(c, o)` from {spp: CPU seconds}, which must hold 1 spp and at least one other count:
    the least-squares line through the 1-spp point."""
    if 1 not in least or len(least) < 2:
        raise ValueError("cpu_model: needs the 1-spp time and at least one other rung")
    t1 = least[1]
    c = sum((n - 1) * (t - t1) for n, t in least.items()) / sum((n - 1) ** 2 for n in least)
    return c, t1 - c


def at_budget(rungs, budget):
    """Error at CPU `budget` from `rungs`, a list of {"cpu", "relrmse"}: interpolated in
    (log CPU, log error) between the rungs that bracket it; outside the ladder, scaled as
    1/sqrt(time) from its nearest end."""
    rungs = sorted(rungs, key=lambda r: r["cpu"])
    lo = [r for r in rungs if r["cpu"] <= budget]
    hi = [r for r in rungs if r["cpu"] >= budget]
    if not lo or not hi:
        end = hi[0] if hi else lo[-1]
        return end["relrmse"] * math.sqrt(end["cpu"] / budget)
    a, b = lo[-1], hi[0]
    if a["cpu"] == b["cpu"]:
        return a["relrmse"]
    s = math.log(budget / a["cpu"]) / math.log(b["cpu"] / a["cpu"])
    if min(a["relrmse"], b["relrmse"]) <= 0.0:
        # A rung equal to its reference has no logarithm: linear in s instead
        return (1 - s) * a["relrmse"] + s * b["relrmse"]
    return math.exp((1 - s) * math.log(a["relrmse"]) + s * math.log(b["relrmse"]))


def _self_test():
    close = lambda x, y: abs(x - y) <= 1e-12 * max(1.0, abs(y))
    # An exact line is recovered: o = 0.2, c = 0.15
    c, o = cpu_model({n: 0.2 + 0.15 * n for n in (1, 2, 4, 8, 64)})
    assert close(c, 0.15) and close(o, 0.2), (c, o)
    # Noise on a short rung moves c little: the long rungs weigh (n - 1)^2
    c, _ = cpu_model({1: 0.35, 2: 0.55, 64: 0.2 + 0.15 * 64})
    assert abs(c - 0.15) < 0.001, c
    # Subtracting the 1-spp render would charge a 4-spp rung t_4 - t_1 = 0.45, three
    # samples' worth; the model charges c * 4 = 0.6
    c, o = cpu_model({1: 0.35, 4: 0.8})
    assert close(c * 4, 0.6) and close(o, 0.2), (c, o)
    for bad in ({2: 1.0, 4: 2.0}, {1: 1.0}):
        try:
            cpu_model(bad)
        except ValueError:
            pass
        else:
            raise AssertionError(f"cpu_model accepted {bad}")
    rungs = [{"cpu": 0.15, "relrmse": 1.0}, {"cpu": 0.3, "relrmse": 0.5}, {"cpu": 0.6, "relrmse": 0.25}]
    # Exact at a rung, whatever the order given
    assert close(at_budget(rungs[::-1], 0.3), 0.5)
    # Between rungs, the measured rate (1/time here, not 1/sqrt(time))
    assert close(at_budget(rungs, 0.45), 0.5 * 0.3 / 0.45)
    # Outside the ladder, sqrt(time) from the nearest end, above and below
    assert close(at_budget(rungs, 2.4), 0.25 * math.sqrt(0.6 / 2.4))
    assert close(at_budget(rungs, 0.075), 1.0 * math.sqrt(0.15 / 0.075))
    # A rung with no error at all (an image equal to its reference) still interpolates
    assert close(at_budget([{"cpu": 1.0, "relrmse": 0.2}, {"cpu": 2.0, "relrmse": 0.0}], math.sqrt(2.0)), 0.1)
    # Interpolation is monotone between rungs whose error falls
    xs = [at_budget(rungs, 0.15 * 1.1**k) for k in range(15)]
    assert all(x >= y for x, y in zip(xs, xs[1:])), xs
    print("budget.py: self-test ok")


if __name__ == "__main__":
    _self_test()
