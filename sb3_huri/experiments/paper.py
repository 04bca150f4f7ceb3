"""The paper's numbers and the orderings it reports, to set our results beside.

From the HuRi paper: Table 1, the success rate (episodes without a fall) of each
method under continuous (U[0, 100] N) and sudden (U[150, 200] N) forces on the centroid, hands and feet,
5 seeds x 10 runs each; the average training return of each method (its Fig. 3); and the risk the critic
reads in its Fig. 5: interquartile range on uneven ground > under a push > walking on the plane; and the
success rates of its appendix on terrains (Tables 8 and 9). The paper
gives no numbers for HuRi without IQR and HuRi with CVaR in Table 1; they are reported without a
reference.
"""

from __future__ import annotations

from sb3_huri.runner.evaluation import TABLE1_SCENARIOS, TERRAIN_SCENARIOS

TABLE1: dict[str, dict[str, float]] = {
    method: dict(zip(TABLE1_SCENARIOS, rates, strict=True))
    for method, rates in {
        "huri-baseline": (0.666, 0.618, 0.658, 0.575, 0.593, 0.589),
        "huri-cvar0.5": (0.687, 0.641, 0.698, 0.609, 0.627, 0.627),
        "huri-no-rnd": (0.819, 0.770, 0.848, 0.776, 0.808, 0.808),
        "huri": (0.856, 0.809, 0.866, 0.832, 0.812, 0.817),
    }.items()
}
"""Success rate per method and Table-1 scenario."""

TERRAINS: dict[str, dict[str, float]] = {
    "huri-baseline": {"multi-terrain": 0.2514, "platform-0.40": 0.6537, "platform-0.45": 0.3901},
    "huri-cvar0.5": {"multi-terrain": 0.4978},
    "huri-no-rnd": {"multi-terrain": 0.4604},
    "huri": {"multi-terrain": 0.5776, "platform-0.40": 0.9273, "platform-0.45": 0.8055},
}
"""Success rate per method on the terrain tests: Table 9 (multi-terrain, methods trained on terrains) and
Table 8 (platforms; baseline and HuRi only)."""
assert all(set(rates) <= set(TERRAIN_SCENARIOS) for rates in TERRAINS.values())

TRAINING_RETURN = {"huri": 90.86, "huri-no-rnd": 86.93, "huri-cvar0.5": 84.17, "huri-baseline": 83.28}
"""Average training return per method (the paper's reward scale, not ours: only the order compares)."""

RANKING = ("huri", "huri-no-rnd", "huri-cvar0.5", "huri-baseline")
"""The paper's order, best first, in every Table-1 column and in the training return."""

RISK_ORDER = ("uneven", "sudden push", "plane")
"""The critic's interquartile range, largest first (Fig. 5): uneven ground, a sudden push, the plane."""

LABELS = {
    "huri-baseline": "Baseline (PPO)",
    "huri-cvar0.5": "CVaR0.5",
    "huri-no-rnd": "HuRi w/o RND",
    "huri-no-iqr": "HuRi w/o IQR",
    "huri": "HuRi",
    "huri-cvar": "HuRi-CVaR",
}
"""The paper's names of the methods."""
