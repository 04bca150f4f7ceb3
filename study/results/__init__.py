"""The campaign's results page, ``docs/results.md``, generated from the queue and its run folders alone.

``write_results`` reads the queue file (``study.campaign.queue``), each entry's run folder
(``state.json``, ``curve.csv``, ``robustness.csv``, ``config.yml``) and the final evaluations written by
``study.campaign.final_evaluation``, and writes the page with its figures beside it
(``docs/results/``), its sections in the order of ``sections.PAGE_ORDER``, which numbers them:

- the campaign's status: every entry's steps, training hours, hardware and state;
- the Table-1 analog: survival per case with its 95% Wilson interval, the Table-1 mean, the paper's
  numbers; HuRi minus PPO on the same robots (Newcombe's paired interval per case, a t interval over the
  robots for the Table-1 mean); means over seeds with a t interval where several seeds were evaluated;
  methods side by side where several share a PPO evaluation: each minus PPO, each minus HuRi;
- ``robustness.png``: every run's robustness learning curve (``robustness.csv``'s Table-1 mean);
- ``returns.png``: the training return against samples per method and protocol (Fig. 3 analog);
- ``tracking.png``: velocity-tracking errors under load, friction and both (Fig. 4 analog);
- ``risk.png``: the critic's IQR and beta on the plane, under a push and on uneven ground (Fig. 5 analog);
- the risk levels each HuRi-family agent sets on the states it visits, per scenario: the shares of states
  below, within and above its IQR band, mean beta and beta_RND, and whether the paper's order holds
  (the campaign measures them after each final evaluation, ``study.scripts.risk_levels`` by hand);
- how far each agent's risk distortion moves the advantages of its own training rollouts from those of a
  neutral and of a constant risk level (measured likewise, ``study.scripts.advantages`` by hand);
- how much of its training rollouts' returns each agent's value explains (HuRi's ``V_beta`` and its
  atoms' mean, PPO's ``V``) and its risk level before a fall (``study.scripts.value_baseline`` by hand);
- ``quadruped.png``: the quadruped's return and terrain level (Fig. 10 analog), its runs of other readings
  (the percentile band) against HuRi and PPO at equal steps while they train, and its Table 8 analog with
  its pairs (and its methods side by side, as in the Table-1 section);
- ``rollout_shape.png``: the robust recipe with 256 robots x 64 steps against 32 x 512, seed for seed,
  and their final evaluations on the same robots where both were evaluated at comparable steps;
- the Table 9 analog: Zerith-1's survival on the multi-terrain test and down the platforms, beside the
  paper's Table 9, and the HuRi-PPO pairs on these cases, on the same robots;
- ``force_magnitude.png``: Zerith-1's survival over the force's magnitude, 0.1x to 1.5x of the paper's,
  the scale at which each agent falls to 50%, and each HuRi-PPO pair's difference on the same robots under
  both readings of the forces on hands and feet (measured as the risk levels are, or by
  ``study.scripts.force_magnitude``);
- ``band.png``: the IQR band in training, the shares of each rollout's states below, within and above it
  and the mean beta, per run with a quantile critic (the robustness and quadruped sections hold the
  runs of every other reading, the percentile band, the risk-neutral critic and the ablations, to HuRi and
  PPO at equal steps while they train: ``results.early_signal``).

The sentences that say what the numbers show (and what they cannot show yet) are generated from the same
numbers: nothing on the page is typed in by hand but the fixed explanations.
"""

from __future__ import annotations

from pathlib import Path

from sb3_huri.runner.files import write_text
from study.campaign.queue import load_queue
from study.results.advantages import advantages_section
from study.results.band import band_section
from study.results.evaluations import SURVIVAL_CASES, load_evaluations, pairs
from study.results.figures import (
    returns_section,
    risk_section,
    robustness_section,
    tracking_section,
)
from study.results.force_magnitude import force_magnitude_section
from study.results.markdown import link
from study.results.methods import side_by_side_findings, side_by_side_section
from study.results.quadruped import quadruped_findings, quadruped_section
from study.results.risk_levels import risk_levels_section
from study.results.rollout_shape import rollout_shape_section
from study.results.tables import (
    findings_section,
    pairs_section,
    status_section,
    table1_section,
)
from study.results.terrains import terrain_section
from study.results.value_baseline import (
    value_baseline_findings,
    value_baseline_section,
)
from zerith_gym import ZERITH1_ID


def write_results(queue_path: Path, out: Path = Path("docs/results.md")) -> Path:
    """Write the results page ``out`` and its figures (in ``out``'s folder, under ``out``'s stem: by default
    ``docs/results/``) from the queue at ``queue_path`` and its run folders; return the page's path."""
    queue_path, out = Path(queue_path).resolve(), Path(out).resolve()
    every_entry = load_queue(queue_path)
    # Zerith-1's comparison from the Table-1 section on; the quadruped's in its own; every entry in the
    # status.
    entries = [entry for entry in every_entry if entry.env_id == ZERITH1_ID]
    quadruped = [entry for entry in every_entry if entry.protocol == "quadruped"]
    evaluations = load_evaluations(entries)
    quadruped_evaluations = load_evaluations(quadruped)
    figures = out.with_suffix("")
    figures.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Results of the training campaign",
        "",
        "Generated by `study.results` from the queue "
        f"`{link(queue_path, out)}` and its run folders; regenerate it rather than edit it. "
        "Final evaluations: "
        f"{entries[0].defaults.eval_episodes if entries else '-'} robots per case (robot i seeded "
        f"{entries[0].defaults.eval_seed if entries else '-'} + i, the same robots for every agent), "
        "20-s episodes at 1 m/s, success = no fall.",
        "",
        *findings_section(
            every_entry,
            evaluations,
            [
                *side_by_side_findings(evaluations, SURVIVAL_CASES),
                *quadruped_findings(quadruped_evaluations),
                *value_baseline_findings(every_entry),
            ],
        ),
        *status_section(every_entry, [*evaluations, *quadruped_evaluations], out),
        *table1_section(evaluations),
        *pairs_section(entries, evaluations),
        *side_by_side_section(evaluations, SURVIVAL_CASES),
        *robustness_section(entries, evaluations, figures, out),
        *returns_section(entries, figures, out),
        *tracking_section(evaluations, figures, out),
        *risk_section(evaluations, figures, out),
        *risk_levels_section(every_entry),
        *advantages_section(every_entry),
        *value_baseline_section(every_entry),
        *quadruped_section(quadruped, quadruped_evaluations, figures, out),
        *rollout_shape_section(entries, evaluations, figures, out),
        *terrain_section(evaluations),
        *force_magnitude_section(evaluations, figures, out),
        *band_section(every_entry, figures, out),
    ]
    write_text(out, "\n".join(lines) + "\n")
    return out


__all__ = ["load_evaluations", "pairs", "write_results"]
