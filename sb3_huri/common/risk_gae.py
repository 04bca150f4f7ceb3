"""GAE on distorted values, under either reading of which risk level a TD error values its states at.

A state's distorted value is ``V_beta(s) = w(beta_s) . Z(s)``, with the weights ``w`` of its own risk level.
When the level changes from state to state, a TD error ``delta_t = r_t + gamma V(s_{t+1}) - V(s_t)`` can be
read two ways:

- ``"state"``: every value at its own state's level, ``r_t + gamma w_{t+1}.Z(s_{t+1}) - w_t.Z(s_t)`` (SB3's
  GAE on the per-state values). Against the neutral critic it adds a potential-based shaping,
  ``gamma psi(s_{t+1}) - psi(s_t)`` with ``psi(s) = V_{beta_s}(s) - V_0(s)``: a state is valued at its own
  level whoever looks at it, and GAE's bootstrapping pulls advantages towards states whose own level values
  them highly.
- ``"step"``: both values at the level of the state the step starts from,
  ``r_t + gamma w_t.Z(s_{t+1}) - w_t.Z(s_t)``: each step's outcome is judged with the risk attitude of the
  state it was taken in.

They differ by ``gamma (V_{beta_t}(s_{t+1}) - V_{beta_{t+1}}(s_{t+1}))`` per TD error, the change of level at
the next state. That term is no potential-based shaping: it does not telescope, so the step reading changes
the advantages even with ``gae_lambda = 1``, where the state reading's levels only move the baseline. With
one level for every state the two are the same.
"""

import numpy as np

TD_LEVELS = ("state", "step")
"""Readings of a TD error's risk levels: each value at its own state's level, or both at the first state's."""


def risk_gae(
    rewards: np.ndarray,
    atoms: np.ndarray,
    weights: np.ndarray,
    episode_starts: np.ndarray,
    last_atoms: np.ndarray,
    last_weights: np.ndarray,
    last_dones: np.ndarray,
    gamma: float,
    gae_lambda: float,
    td_level: str,
    bootstrap_atoms: np.ndarray | None = None,
    bootstrap_weights: np.ndarray | None = None,
) -> np.ndarray:
    """Advantages of a rollout by GAE on the distorted values, under the reading ``td_level``.

    Terminal steps do not bootstrap; an episode truncated at step ``t`` bootstraps from its final state's
    atoms (``bootstrap_atoms[t]``), valued at that state's own level (``bootstrap_weights[t]``) with
    ``"state"``, at ``w_t`` with ``"step"``.

    :param rewards: shape ``(T, E)``
    :param atoms: sorted atoms of ``Z(s_t)``, shape ``(T, E, N)``
    :param weights: distortion weights of each state's level, shape ``(T, E, N)``
    :param episode_starts: whether ``s_t`` starts an episode, shape ``(T, E)`` (SB3's convention)
    :param last_atoms: sorted atoms of the state after the rollout, shape ``(E, N)``
    :param last_weights: its weights, shape ``(E, N)`` (unused by ``"step"``)
    :param last_dones: whether the episode ended on the rollout's last step, shape ``(E,)``
    :param td_level: ``"state"`` or ``"step"`` (module docstring)
    :param bootstrap_atoms: final states' atoms of the episodes truncated at each step (zeros elsewhere),
        shape ``(T, E, N)``; ``None`` when no episode was truncated
    :param bootstrap_weights: their weights, shape ``(T, E, N)`` (needed by ``"state"`` with time-outs)
    :return: advantages, shape ``(T, E)``
    """
    if td_level not in TD_LEVELS:
        raise ValueError(f"Unknown td_level {td_level!r}: expected one of {list(TD_LEVELS)}")
    atoms, weights = np.asarray(atoms, dtype=np.float64), np.asarray(weights, dtype=np.float64)
    last_atoms = np.asarray(last_atoms, dtype=np.float64)
    next_atoms = np.concatenate([atoms[1:], last_atoms[None]])
    continues = 1.0 - np.concatenate([episode_starts[1:], np.asarray(last_dones)[None]]).astype(np.float64)
    here = np.einsum("ten,ten->te", weights, atoms)
    rewards = np.asarray(rewards, dtype=np.float64)
    if td_level == "step":
        there = np.einsum("ten,ten->te", weights, next_atoms)
        if bootstrap_atoms is not None:
            rewards = rewards + gamma * np.einsum("ten,ten->te", weights, bootstrap_atoms)
    else:
        there = np.concatenate([here[1:], np.einsum("en,en->e", last_weights, last_atoms)[None]])
        if bootstrap_atoms is not None:
            if bootstrap_weights is None:
                raise ValueError('td_level "state" with time-outs needs the final states\' bootstrap_weights')
            rewards = rewards + gamma * np.einsum("ten,ten->te", bootstrap_weights, bootstrap_atoms)
    deltas = rewards + gamma * continues * there - here
    advantages = np.empty_like(deltas)
    running = np.zeros(deltas.shape[1])
    for step in reversed(range(deltas.shape[0])):
        running = deltas[step] + gamma * gae_lambda * continues[step] * running
        advantages[step] = running
    return advantages.astype(np.float32)
