"""What lets a saved HuRiPPO load where its saved attributes or optimizer state no longer fit as they are.

SB3's ``load`` builds a model with the default arguments, then restores the saved attributes by name and the
saved state dicts. Two kinds of save need more than that, so that every committed run keeps loading:

- a model saved by an earlier version: its method was named by ``variant`` (``method_of_saved`` gives today's
  name), and one saved before the IQR band had a reading of its own has no ``iqr_band`` (it takes its
  method's, the absolute band), nor one saved before the TD error's levels had a reading a ``td_level``
  (its method's: ``"state"``);
- a model saved before HuRiPPO took SB3's PPO defaults (it has no ``network_defaults``): where its
  ``policy_kwargs`` leave out ``net_arch`` or ``activation_fn``, it was built with the paper's networks
  (``EARLIER_NETWORK``);
- a model saved with one learning rate, loaded with ``critic_learning_rate``: its optimizer state holds one
  parameter group where the optimizer now has the actor's and the critic's, so Adam starts afresh.
"""

import warnings
from typing import Any

import torch as th
from torch import nn

from sb3_huri.huri.methods import METHODS, method_of_saved

EARLIER_NETWORK: dict[str, Any] = {
    "net_arch": dict(pi=[512, 256, 128], vf=[512, 256, 128]),
    "activation_fn": nn.ELU,
}
"""HuRiPolicy's networks before it took SB3's defaults: an earlier save's, where its kwargs name none."""
NETWORK_DEFAULTS = "ppo"
"""The ``network_defaults`` a new model saves: its policy's unnamed networks are SB3's PPO defaults."""


def upgrade_saved_attributes(attributes: dict[str, Any]) -> None:
    """Bring a loaded model's attributes (its ``__dict__``, holding ``method``) to today's names in place:
    ``variant`` becomes ``method``, and a missing ``iqr_band`` or ``td_level`` takes the method's
    (``"absolute"`` and ``"state"`` for a method no preset names), and a model saved before there were
    ``network_defaults`` gets the networks it was built with where its ``policy_kwargs`` name none
    (``EARLIER_NETWORK``; also when ``load`` is given other ``policy_kwargs``)."""
    attributes["method"] = method_of_saved(attributes) or attributes["method"]
    if "network_defaults" not in attributes:
        attributes["network_defaults"] = "paper"
        attributes["policy_kwargs"] = {**EARLIER_NETWORK, **(attributes.get("policy_kwargs") or {})}
    attributes.pop("variant", None)
    preset = METHODS.get(attributes["method"])
    attributes.setdefault("iqr_band", preset.iqr_band if preset is not None else "absolute")
    attributes.setdefault("td_level", preset.td_level if preset is not None else "state")


def fitting_optimizer_state(params: dict[str, Any], optimizer: th.optim.Optimizer) -> dict[str, Any]:
    """`params` (the state dicts SB3's ``set_parameters`` loads, by name) as `optimizer` can load them:
    without the saved ``"policy.optimizer"`` state, with a warning, where its parameter groups are not
    `optimizer`'s; else `params` itself."""
    saved = params.get("policy.optimizer")
    if saved is None or len(saved["param_groups"]) == len(optimizer.param_groups):
        return params
    warnings.warn(
        "the saved model learned with one learning rate; with critic_learning_rate its optimizer "
        "has actor and critic groups: the saved Adam moments are dropped, the weights are kept",
        stacklevel=4,
    )
    return {key: value for key, value in params.items() if key != "policy.optimizer"}
