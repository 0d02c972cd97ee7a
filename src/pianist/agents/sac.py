"""Soft actor-critic in JAX; DroQ (dropout + layer norm critics) and REDQ (subsampled target
minimum over a large ensemble) are settings of :class:`pianist.agents.config.SACConfig`.

The agent state is an immutable pytree (:class:`SACState`); :meth:`SAC.update` and
:meth:`SAC.update_many` are jitted pure functions ``state, batch -> state, metrics``. One update
is, as in the original training code: critic step (target from the current actor and
temperature, target critic EMA after), actor step against the new critics, temperature step
from the actor's batch entropy. Everything is float32.
"""

from __future__ import annotations

import dataclasses
import math
from functools import lru_cache, partial
from typing import Any

import flax
import jax
import jax.numpy as jnp
import numpy as np
import optax

from pianist.agents.config import SACConfig
from pianist.agents.networks import Actor, CriticEnsemble
from pianist.agents.replay import Batch

_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)


@flax.struct.dataclass
class SACState:
    """Parameters, optimiser states, the PRNG key (uint32 (2,)) and the update counter."""

    actor: Any
    critic: Any
    target_critic: Any
    log_temp: jax.Array
    actor_opt: Any
    critic_opt: Any
    temp_opt: Any
    rng: jax.Array
    updates: jax.Array


def tanh_gaussian_sample(
    mean: jax.Array, log_std: jax.Array, key: jax.Array
) -> tuple[jax.Array, jax.Array]:
    """Reparameterised sample of tanh(N(mean, exp(log_std)^2)).

    Args: mean, log_std (B, A). Returns: action (B, A) in (-1, 1), log probability (B,).
    """
    eps = jax.random.normal(key, mean.shape, mean.dtype)
    u = mean + jnp.exp(log_std) * eps
    # log(1 - tanh(u)^2) written without cancellation for large |u|.
    log_det = 2.0 * (math.log(2.0) - u - jax.nn.softplus(-2.0 * u))
    log_prob = jnp.sum(-0.5 * eps**2 - log_std - _HALF_LOG_2PI - log_det, axis=-1)
    return jnp.tanh(u), log_prob


class SAC:
    """The networks, optimisers and jitted update of one agent (observation size D, action A)."""

    def __init__(self, obs_dim: int, action_dim: int, config: SACConfig) -> None:
        self.obs_dim, self.action_dim, self.config = obs_dim, action_dim, config
        c = config
        self.actor_def = Actor(
            c.hidden_dims,
            action_dim,
            c.activation,
            c.log_std_min,
            c.log_std_max,
            c.zero_mean_init,
            c.init_log_std,
        )
        critic = partial(
            CriticEnsemble,
            hidden_dims=c.hidden_dims,
            activation=c.activation,
            dropout=c.critic_dropout,
            layer_norm=c.critic_layer_norm,
        )
        self.critic_def = critic(num=c.num_qs)
        self.target_def = critic(num=c.num_min_qs or c.num_qs)
        self.actor_tx = optax.adam(c.actor_lr)
        self.critic_tx = optax.adam(c.critic_lr)
        self.temp_tx = optax.adam(c.temp_lr)
        self.target_entropy = float(c.target_entropy_per_dim * action_dim)
        self.update = jax.jit(self._update)
        self.update_many = jax.jit(self._update_many)

    # ----------------------------------------------------------------------------- state

    def init(self, seed: int) -> SACState:
        """Fresh parameters and optimiser states from ``seed``."""
        rng, k_actor, k_critic = jax.random.split(jax.random.PRNGKey(seed), 3)
        obs = jnp.zeros((1, self.obs_dim), jnp.float32)
        action = jnp.zeros((1, self.action_dim), jnp.float32)
        actor = self.actor_def.init(k_actor, obs)["params"]
        critic = self.critic_def.init(k_critic, obs, action)["params"]
        log_temp = jnp.asarray(math.log(self.config.init_temperature), jnp.float32)
        return SACState(
            actor=actor,
            critic=critic,
            target_critic=critic,
            log_temp=log_temp,
            actor_opt=self.actor_tx.init(actor),
            critic_opt=self.critic_tx.init(critic),
            temp_opt=self.temp_tx.init(log_temp),
            rng=rng,
            updates=jnp.zeros((), jnp.int32),
        )

    # ----------------------------------------------------------------------------- losses

    def critic_loss(
        self, critic: Any, state: SACState, batch: Batch, key: jax.Array
    ) -> tuple[jax.Array, dict[str, jax.Array]]:
        """Mean over critics and batch of (Q_i(s, a) - y)^2 with the soft TD target y (B,).

        Returns the loss and terms: q (N, B), target (B,), next_log_prob (B,).
        """
        c = self.config
        k_next, k_sub, k_target, k_drop = jax.random.split(key, 4)
        mean, log_std = self.actor_def.apply({"params": state.actor}, batch.next_obs)
        # flax annotates apply's result as maybe (output, variables): only with mutable=.
        next_action, next_log_prob = tanh_gaussian_sample(mean, log_std, k_next)  # type: ignore[arg-type]
        target_params = state.target_critic
        if c.num_min_qs is not None and c.num_min_qs < c.num_qs:
            chosen = jax.random.choice(k_sub, c.num_qs, (c.num_min_qs,), replace=False)
            target_params = jax.tree_util.tree_map(lambda p: p[chosen], target_params)
        next_q = self.target_def.apply(  # type: ignore[union-attr]  # flax: as above
            {"params": target_params}, batch.next_obs, next_action, True, rngs={"dropout": k_target}
        ).min(axis=0)
        bootstrap = c.discount * batch.discount
        target = batch.reward + bootstrap * next_q
        if c.backup_entropy:
            target = target - bootstrap * jnp.exp(state.log_temp) * next_log_prob
        target = jax.lax.stop_gradient(target)
        q = self.critic_def.apply(
            {"params": critic}, batch.obs, batch.action, True, rngs={"dropout": k_drop}
        )
        loss = jnp.mean((q - target[None, :]) ** 2)
        return loss, {"q": q, "target": target, "next_log_prob": next_log_prob}

    def actor_loss(
        self, actor: Any, state: SACState, batch: Batch, key: jax.Array
    ) -> tuple[jax.Array, dict[str, jax.Array]]:
        """Mean over the batch of temperature * log pi(a|s) - mean_i Q_i(s, a), a ~ pi, plus
        ``residual_penalty`` * sum_i tanh(mean_i)^2 (the deterministic action's size).

        Returns the loss and terms: log_prob (B,), q (B,) (ensemble mean), size (B,).
        """
        k_action, k_drop = jax.random.split(key)
        mean, log_std = self.actor_def.apply({"params": actor}, batch.obs)
        # flax annotates apply's result as maybe (output, variables): only with mutable=.
        action, log_prob = tanh_gaussian_sample(mean, log_std, k_action)  # type: ignore[arg-type]
        q = self.critic_def.apply(  # type: ignore[union-attr]  # flax: as above
            {"params": state.critic}, batch.obs, action, True, rngs={"dropout": k_drop}
        ).mean(axis=0)
        size = jnp.sum(jnp.tanh(mean) ** 2, axis=-1)
        loss = jnp.mean(jnp.exp(state.log_temp) * log_prob - q)
        if self.config.residual_penalty > 0:
            loss = loss + self.config.residual_penalty * jnp.mean(size)
        return loss, {"log_prob": log_prob, "q": q, "size": size}

    def temperature_loss(self, log_temp: jax.Array, entropy: jax.Array) -> jax.Array:
        """temperature * (entropy - target entropy), entropy a scalar batch estimate."""
        return jnp.exp(log_temp) * (jax.lax.stop_gradient(entropy) - self.target_entropy)

    # ----------------------------------------------------------------------------- updates

    def _update(self, state: SACState, batch: Batch) -> tuple[SACState, dict[str, jax.Array]]:
        rng, k_critic, k_actor = jax.random.split(state.rng, 3)
        (c_loss, c_terms), grads = jax.value_and_grad(self.critic_loss, has_aux=True)(
            state.critic, state, batch, k_critic
        )
        updates, critic_opt = self.critic_tx.update(grads, state.critic_opt, state.critic)
        critic = optax.apply_updates(state.critic, updates)
        target = optax.incremental_update(critic, state.target_critic, self.config.tau)
        state = dataclasses.replace(
            state, critic=critic, critic_opt=critic_opt, target_critic=target
        )

        (a_loss, a_terms), grads = jax.value_and_grad(self.actor_loss, has_aux=True)(
            state.actor, state, batch, k_actor
        )
        updates, actor_opt = self.actor_tx.update(grads, state.actor_opt, state.actor)
        actor = optax.apply_updates(state.actor, updates)

        entropy = -jnp.mean(a_terms["log_prob"])
        t_loss, grad = jax.value_and_grad(self.temperature_loss)(state.log_temp, entropy)
        updates, temp_opt = self.temp_tx.update(grad, state.temp_opt, state.log_temp)
        log_temp = optax.apply_updates(state.log_temp, updates)

        state = dataclasses.replace(
            state,
            actor=actor,
            actor_opt=actor_opt,
            log_temp=log_temp,
            temp_opt=temp_opt,
            rng=rng,
            updates=state.updates + 1,
        )
        metrics = {
            "critic_loss": c_loss,
            "q": jnp.mean(c_terms["q"]),
            "actor_loss": a_loss,
            "entropy": entropy,
            "temperature": jnp.exp(log_temp),
            "temperature_loss": t_loss,
            "mean_action_sq": jnp.mean(a_terms["size"]) / self.action_dim,
        }
        return state, metrics

    def _update_many(
        self, state: SACState, batches: Batch
    ) -> tuple[SACState, dict[str, jax.Array]]:
        """K updates in one call: ``batches`` fields carry a leading K axis. Metrics: K means."""
        state, metrics = jax.lax.scan(self._update, state, batches)
        return state, jax.tree_util.tree_map(jnp.mean, metrics)


# --------------------------------------------------------------------------------- acting


def actor_weights(params: Any) -> list[tuple[np.ndarray, np.ndarray]]:
    """Actor parameters -> [(W (in, out), b (out,)), ...]: hidden layers, then mean, log std."""
    params = jax.device_get(params)
    hidden = params["MLP_0"]
    layers = [hidden[f"Dense_{i}"] for i in range(len(hidden))]
    layers += [params["mean"], params["log_std"]]
    return [(np.array(p["kernel"], np.float32), np.array(p["bias"], np.float32)) for p in layers]


@lru_cache(maxsize=8)
def make_agent(obs_dim: int, action_dim: int, config: SACConfig) -> SAC:
    """A shared :class:`SAC` per (sizes, config), so its jitted updates compile once."""
    return SAC(obs_dim, action_dim, config)
