"""Behaviour cloning: one MLP policy from demonstrations of many songs, and DAgger.

The policy reads the environment's own observation (state and goal, no task wrapper) and
writes the normalised action in [-1, 1]^A. Its features (:class:`Features`) are every
observation entry, in sorted key order, each flattened in C order; ``goal`` keeps its first
``goal_rows`` rows (the current frame and the look-ahead). They are standardised with the
training data's per-feature mean and std (std floored at :data:`STD_FLOOR`, constant features
are only centred), then an MLP (hidden sizes configurable; the paper's policies go up to 1024
wide) with a tanh output is fitted to the demonstrated actions by mean squared error with Adam,
each minibatch's standardised features perturbed by Gaussian noise (``input_noise``) so that
the policy acts like the demonstration also a little off the demonstrated states.

DAgger (:func:`dagger`): the current policy plays the training songs; at every state it
visits the planner, run in lock-step on the same environment, proposes its action, which
becomes that state's label (the planner's per-finger memory follows its own proposals, its
forearm servo reads the state the policy brought about); the labelled states join the data
and the policy is trained again, for N rounds.

A trained policy is a folder (:func:`save_policy`, written whole or not at all)::

    bc.json        format, features, network, the environment options, training facts
    weights.npz    W0, b0, W1, b1, ... (the output layer last), feature mean and std

and plays in NumPy with :class:`BCController` (``--controller bc:DIR``). JAX is imported
only by the training functions.
"""

from __future__ import annotations

import json
import time
import zipfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from pianist.control.base import BaseController
from pianist.files import atomic_dir

if TYPE_CHECKING:
    from pianist.env.multi_song import MultiSongEnv

FORMAT = "pianist-bc"
VERSION = 1
CONFIG_FILE = "bc.json"
WEIGHTS_FILE = "weights.npz"
#: Smallest std a feature is divided by (features nearly constant in the data, e.g. a key
#: never pressed, would otherwise be blown up when the policy meets them elsewhere).
STD_FLOOR = 1e-2

Log = Callable[[str], None]
_CHUNK = 500  # Adam steps per compiled call (and per log line)


# ----------------------------------------------------------------------------- features


@dataclass(frozen=True)
class Features:
    """Observation dict -> flat float32 vector (D,): the entries ``keys`` (sorted), each
    raveled; ``goal`` cut to its first ``goal_rows`` rows. ``shapes``: each entry's shape."""

    keys: tuple[str, ...]
    shapes: tuple[tuple[int, ...], ...]
    goal_rows: int

    @classmethod
    def from_shapes(cls, shapes: Mapping[str, Sequence[int]], goal_rows: int | None = None):
        """The features of observations with these entry shapes (one observation's, no batch
        axis); ``goal_rows`` None keeps the whole goal."""
        keys = tuple(sorted(shapes))
        if "goal" not in shapes:
            raise ValueError("the observation has no 'goal' entry")
        rows = int(shapes["goal"][0])
        goal_rows = rows if goal_rows is None else goal_rows
        if not 1 <= goal_rows <= rows:
            raise ValueError(f"goal_rows must be in 1..{rows}, not {goal_rows}")
        return cls(keys, tuple(tuple(int(n) for n in shapes[k]) for k in keys), goal_rows)

    @classmethod
    def from_space(cls, space: gym.spaces.Space, goal_rows: int | None = None) -> Features:
        """The features of a Dict observation space (a :class:`PianoEnv`'s)."""
        if not isinstance(space, gym.spaces.Dict):
            raise ValueError(f"behaviour cloning reads a Dict observation, not {space}")
        shapes = {k: s.shape for k, s in space.spaces.items() if s.shape is not None}
        return cls.from_shapes(shapes, goal_rows)

    @property
    def dim(self) -> int:
        """D, the feature vector's length."""
        return sum(self._size(k, s) for k, s in zip(self.keys, self.shapes, strict=True))

    def _size(self, key: str, shape: tuple[int, ...]) -> int:
        if key == "goal":
            return self.goal_rows * int(np.prod(shape[1:]))
        return int(np.prod(shape))

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        """One observation -> (D,) float32."""
        return self.batch({k: np.asarray(obs[k])[None] for k in self.keys})[0]

    def batch(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        """Stacked observations (name -> (N, ...)) -> (N, D) float32."""
        n = len(obs[self.keys[0]])
        parts = []
        for key in self.keys:
            value = np.asarray(obs[key])
            if key == "goal":
                value = value[:, : self.goal_rows]
            parts.append(value.reshape(n, -1).astype(np.float32, copy=False))
        return np.concatenate(parts, axis=1)

    def check(self, space: gym.spaces.Space) -> None:
        """Refuse an observation space these features were not made for.

        Raises:
            ValueError: other entries or shapes.
        """
        other = Features.from_space(space, None)
        if other.keys != self.keys or other.shapes != self.shapes:
            raise ValueError(
                "this policy was trained on observations "
                f"{dict(zip(self.keys, self.shapes, strict=True))}, the environment gives "
                f"{dict(zip(other.keys, other.shapes, strict=True))}"
            )

    def to_dict(self) -> dict[str, Any]:
        return {
            "keys": list(self.keys),
            "shapes": [list(s) for s in self.shapes],
            "goal_rows": self.goal_rows,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Features:
        return cls(
            tuple(data["keys"]), tuple(tuple(s) for s in data["shapes"]), int(data["goal_rows"])
        )


# ----------------------------------------------------------------------------- the policy


@dataclass(frozen=True)
class BCConfig:
    """How a behaviour-cloning policy is built and trained."""

    hidden_dims: tuple[int, ...] = (256, 256)
    """Hidden layer widths (the paper's policies: up to 1024)."""
    activation: str = "gelu"
    learning_rate: float = 1e-3
    batch_size: int = 256
    steps: int = 3000
    """Adam steps of one training (a DAgger round trains this many again)."""
    input_noise: float = 0.3
    """Std of Gaussian noise added to the standardised features of each minibatch (0: none):
    the policy learns to act the same a little off the demonstrated states."""
    seed: int = 0


def config_dict(config: BCConfig) -> dict[str, Any]:
    """``config`` as JSON-ready values."""
    data = asdict(config)
    data["hidden_dims"] = list(config.hidden_dims)
    return data


class NumpyMLP:
    """The trained network's forward pass in float32 NumPy: standardise, hidden layers,
    tanh output. ``layers``: [(W (in, out), b (out,)), ...], the output layer last."""

    def __init__(
        self,
        layers: list[tuple[np.ndarray, np.ndarray]],
        mean: np.ndarray,
        std: np.ndarray,
        activation: str,
    ) -> None:
        from pianist.agents.policy import _ACTIVATIONS

        self.layers = layers
        self.mean, self.std = mean.astype(np.float32), std.astype(np.float32)
        self.activation_name = activation
        self.activation = _ACTIVATIONS[activation]
        self.obs_dim = layers[0][0].shape[0]
        self.action_dim = layers[-1][0].shape[1]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Features (D,) or (N, D) -> actions (A,) or (N, A) in [-1, 1]."""
        h = (x - self.mean) / self.std
        for w, b in self.layers[:-1]:
            h = self.activation(h @ w + b)
        w, b = self.layers[-1]
        return np.tanh(h @ w + b).astype(np.float32)


@dataclass
class BCPolicy:
    """A trained policy: its features, network, and the environment options it plays in."""

    features: Features
    net: NumpyMLP
    env_options: dict[str, Any] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)

    def act(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        """Observation dict -> action (A,) float32 in [-1, 1]."""
        return self.net(self.features(obs))


def standardiser(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-feature mean and std (D,) of features (N, D); std floored at :data:`STD_FLOOR`,
    and 1 for features that never change."""
    mean = x.mean(axis=0)
    std = x.std(axis=0)
    std = np.where(std < 1e-8, 1.0, np.maximum(std, STD_FLOOR))
    return mean.astype(np.float32), std.astype(np.float32)


# ----------------------------------------------------------------------------- training (JAX)


def _network(config: BCConfig, action_dim: int) -> Any:
    import flax.linen as nn

    from pianist.agents.networks import MLP

    class BCNet(nn.Module):
        @nn.compact
        def __call__(self, x):
            h = MLP(config.hidden_dims, config.activation)(x)
            out = nn.Dense(action_dim, kernel_init=nn.initializers.xavier_uniform())(h)
            return nn.tanh(out)

    return BCNet()


class Trainer:
    """Fits the network to (features, actions) pairs by MSE with Adam.

    ``x`` (N, D) float32 features (raw: standardised here with ``mean``/``std``), ``y`` (N, A)
    actions in [-1, 1]. :meth:`fit` may be called again with more data (DAgger): training
    goes on from the current weights and optimiser state.
    """

    def __init__(self, config: BCConfig, dim: int, action_dim: int, mean, std) -> None:
        import jax
        import jax.numpy as jnp
        import optax

        self.config = config
        self.mean, self.std = np.asarray(mean, np.float32), np.asarray(std, np.float32)
        self.net = _network(config, action_dim)
        self._rng = np.random.default_rng(config.seed)  # minibatch draws
        self.params = self.net.init(
            jax.random.PRNGKey(config.seed), jnp.zeros((1, dim), jnp.float32)
        )["params"]
        self.optimizer = optax.adam(config.learning_rate)
        self.opt_state = self.optimizer.init(self.params)
        net, optimizer = self.net, self.optimizer

        def loss_fn(params, x, y):
            return jnp.mean((net.apply({"params": params}, x) - y) ** 2)

        noise = config.input_noise

        def update(carry, step, xs, ys):
            params, opt_state = carry
            index, key = step
            x = xs[index]
            if noise > 0:  # states a little off the demonstrations, labelled the same
                x = x + noise * jax.random.normal(key, x.shape)
            loss, grads = jax.value_and_grad(loss_fn)(params, x, ys[index])
            updates, opt_state = optimizer.update(grads, opt_state, params)
            return (optax.apply_updates(params, updates), opt_state), loss

        def chunk(params, opt_state, indices, key, xs, ys):
            # Many steps in one compiled call (lax.scan): a Python loop of small steps is
            # dominated by dispatch.
            keys = jax.random.split(key, indices.shape[0])
            (params, opt_state), losses = jax.lax.scan(
                lambda carry, step: update(carry, step, xs, ys),
                (params, opt_state),
                (indices, keys),
            )
            return params, opt_state, losses

        self._loss = jax.jit(loss_fn)
        self._chunk = jax.jit(chunk)

    def _standardise(self, x: np.ndarray) -> np.ndarray:
        return ((np.asarray(x, np.float32) - self.mean) / self.std).astype(np.float32)

    def loss(self, x: np.ndarray, y: np.ndarray) -> float:
        """Mean squared action error on (x, y)."""
        return float(self._loss(self.params, self._standardise(x), np.asarray(y, np.float32)))

    def fit(self, x: np.ndarray, y: np.ndarray, steps: int, log: Log | None = None) -> list[float]:
        """``steps`` Adam steps on minibatches drawn from (x, y); returns each step's loss."""
        import jax
        import jax.numpy as jnp

        xs = jnp.asarray(self._standardise(x))
        ys = jnp.asarray(np.asarray(y, np.float32))
        n = xs.shape[0]
        batch = min(self.config.batch_size, n)
        losses: list[float] = []
        start = time.perf_counter()
        done = 0
        while done < steps:
            size = min(_CHUNK, steps - done)
            indices = self._rng.integers(0, n, (size, batch))
            key = jax.random.PRNGKey(self._rng.integers(2**31))
            self.params, self.opt_state, chunk_losses = self._chunk(
                self.params, self.opt_state, jnp.asarray(indices), key, xs, ys
            )
            losses.extend(np.asarray(chunk_losses).tolist())
            done += size
            if log is not None:
                log(
                    f"  step {done}/{steps}: loss {np.mean(losses[-size:]):.5f} "
                    f"({time.perf_counter() - start:.0f} s)"
                )
        return [float(v) for v in losses]

    def layers(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The weights as NumPy [(W, b), ...] in layer order, the output layer last."""
        mlp = self.params["MLP_0"]
        hidden = [mlp[f"Dense_{i}"] for i in range(len(self.config.hidden_dims))]
        out = self.params["Dense_0"]
        return [(np.asarray(d["kernel"]), np.asarray(d["bias"])) for d in [*hidden, out]]

    def policy(self, features: Features, env_options: Mapping[str, Any]) -> BCPolicy:
        """The current network as a :class:`BCPolicy` (NumPy)."""
        net = NumpyMLP(self.layers(), self.mean, self.std, self.config.activation)
        return BCPolicy(features, net, dict(env_options))


# ----------------------------------------------------------------------------- data


@dataclass
class Demonstrations:
    """Features (N, D) and action labels (N, A) of many steps, with the features' layout."""

    features: Features
    x: np.ndarray
    y: np.ndarray

    def extend(self, x: np.ndarray, y: np.ndarray) -> None:
        self.x = np.concatenate([self.x, x])
        self.y = np.concatenate([self.y, y])


def demonstrations(
    episodes: Iterable[tuple[Mapping[str, np.ndarray], np.ndarray]],
    goal_rows: int | None = None,
) -> Demonstrations:
    """Training pairs from episodes, each (observations name -> (T + 1, ...) as Minari stores
    them, actions (T, A)): the T observations before each action, with that action.

    Raises:
        ValueError: no steps, or episodes whose observations have other entries or shapes.
    """
    features: Features | None = None
    xs, ys = [], []
    for observations, actions in episodes:
        shapes = {k: np.asarray(v).shape[1:] for k, v in observations.items()}
        these = Features.from_shapes(shapes, goal_rows)
        if features is None:
            features = these
        elif these != features:
            raise ValueError("episodes with other observation entries or shapes")
        T = len(actions)
        xs.append(features.batch({k: np.asarray(v)[:T] for k, v in observations.items()}))
        ys.append(np.asarray(actions, np.float32))
    if features is None or not sum(len(y) for y in ys):
        raise ValueError("no demonstration steps")
    return Demonstrations(features, np.concatenate(xs), np.concatenate(ys))


def minari_episodes(dataset: Any) -> Iterable[tuple[dict[str, np.ndarray], np.ndarray]]:
    """(observations, actions) of every episode of a loaded Minari dataset.

    Raises:
        ValueError: the dataset's file is damaged (HDF5 reports it as a RuntimeError or an
            OSError while the episodes are read).
    """
    try:
        for episode in dataset.iterate_episodes():
            yield dict(episode.observations), np.asarray(episode.actions)
    except (RuntimeError, OSError, KeyError) as exc:
        name = getattr(getattr(dataset, "spec", None), "dataset_id", "the dataset")
        raise ValueError(
            f"{name}: its episodes cannot be read, the file is damaged ({exc})"
        ) from None


def train_bc(
    data: Demonstrations,
    config: BCConfig = BCConfig(),
    env_options: Mapping[str, Any] | None = None,
    log: Log | None = None,
) -> tuple[BCPolicy, Trainer]:
    """Train a policy on ``data`` (``config.steps`` Adam steps); returns it and its trainer
    (to train on, e.g. by :func:`dagger`). ``env_options``: the :class:`PianoEnv` options the
    demonstrations were played in (the policy plays in the same)."""
    mean, std = standardiser(data.x)
    trainer = Trainer(config, data.features.dim, data.y.shape[1], mean, std)
    losses = trainer.fit(data.x, data.y, config.steps, log)
    policy = trainer.policy(data.features, env_options or {})
    policy.info = {"steps": len(data.x), "final_loss": float(np.mean(losses[-100:]))}
    return policy, trainer


# ----------------------------------------------------------------------------- playing


class BCController(BaseController):
    """A behaviour-cloning policy as a controller (``--controller bc:DIR``).

    Plays in the environment its demonstrations were played in (:meth:`env_options`);
    deterministic.
    """

    def __init__(self, policy: BCPolicy | str | Path) -> None:
        self.policy = policy if isinstance(policy, BCPolicy) else load_policy(policy)

    def env_options(self, song: Any = None) -> dict[str, Any]:
        """The :class:`pianist.env.PianoEnv` options of the demonstrations, whatever the song."""
        return dict(self.policy.env_options)

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self.policy.features.check(env.observation_space)
        if env.action_space.shape != (self.policy.net.action_dim,):
            raise ValueError(
                f"the policy writes {self.policy.net.action_dim} action values, the environment "
                f"takes {env.action_space.shape}"
            )

    def act(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
        return self.policy.act(observation)


# ----------------------------------------------------------------------------- DAgger


@dataclass
class Rollout:
    """One episode played by a policy, labelled by the planner.

    ``x`` (T, D) features of the visited states, ``labels`` (T, A) the planner's action in
    each, ``actions`` (T, A) what the policy played, ``f1`` the episode's key F1.
    """

    song: str
    x: np.ndarray
    labels: np.ndarray
    actions: np.ndarray
    f1: float


def labelled_rollout(policy: BCPolicy, song: Any, seed: int = 0, expert: Any = None) -> Rollout:
    """Play ``song`` with ``policy`` and label every visited state with ``expert``'s action
    (default a new :class:`pianist.control.planner.IKPlanner`), the expert acting in
    lock-step on the same environment (it reads the simulator through the environment's
    control handle, so it sees the state the policy brought about; its own memory follows its
    own proposals).
    """
    from pianist.eval.metrics import precision_recall_f1
    from pianist.eval.session import make_env

    if expert is None:
        from pianist.control.planner import IKPlanner

        expert = IKPlanner()
    controller = BCController(policy)
    env = make_env(song, controller)
    obs, _ = env.reset(seed=seed)
    expert.reset(env, seed=seed)
    controller.reset(env, seed)
    xs, labels, actions, pressed, goal = [], [], [], [], []
    done = False
    while not done:
        xs.append(policy.features(obs))
        labels.append(np.asarray(expert.act(obs), np.float32))
        action = controller.act(obs)
        actions.append(action)
        obs, _, terminated, truncated, info = env.step(action)
        pressed.append(info["active_keys"])
        goal.append(info["goal_keys"])
        done = terminated or truncated
    env.close()
    f1 = precision_recall_f1(np.array(pressed), np.array(goal))["f1"]
    name = getattr(song, "name", str(song))
    return Rollout(name, np.array(xs), np.array(labels), np.array(actions), f1)


def labelled_rollouts(
    policy: BCPolicy, songs: Sequence[Any], seed: int, workers: int = 1
) -> Iterable[Rollout]:
    """:func:`labelled_rollout` of each song (seed ``seed``), in song order; with ``workers``
    > 1 that many songs are played at once, each in its own spawned process (the policy is
    NumPy: it pickles)."""
    if workers <= 1 or len(songs) <= 1:
        for song in songs:
            yield labelled_rollout(policy, song, seed=seed)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(workers, len(songs)), mp_context=context) as pool:
        futures = [pool.submit(labelled_rollout, policy, song, seed) for song in songs]
        for future in futures:
            yield future.result()


def dagger(
    data: Demonstrations,
    songs: Sequence[Any],
    rounds: int,
    config: BCConfig = BCConfig(),
    env_options: Mapping[str, Any] | None = None,
    log: Log | None = None,
    trained: tuple[BCPolicy, Trainer] | None = None,
    workers: int = 1,
) -> tuple[BCPolicy, list[dict[str, Any]]]:
    """Behaviour cloning, then ``rounds`` DAgger rounds on ``songs``.

    Each round plays every song once with the current policy (seed = the round), labels the
    visited states with the planner's actions (:func:`labelled_rollout`), adds them to the
    data and trains ``config.steps`` more steps on all of it (from the current weights; the
    feature standardisation stays the demonstrations'). Returns the final policy and one row
    per round: round, the F1 of each song as the round's policy played it, steps of data.
    ``trained``: a policy already trained on ``data`` and its trainer (skips the first fit).
    ``workers``: songs played at once, each in its own process (:func:`labelled_rollouts`).
    """
    say = log or (lambda _line: None)
    if rounds < 0:
        raise ValueError(f"DAgger rounds must be >= 0, not {rounds}")
    if rounds and not songs:
        raise ValueError("DAgger needs the songs to play")
    if rounds:
        from pianist.control.planner import ENV_OPTIONS

        dofs = tuple((env_options or {}).get("forearm_dofs", ("tx", "ty")))
        if dofs != ENV_OPTIONS["forearm_dofs"]:
            raise ValueError(
                f"DAgger's teacher, the planner, plays with forearm slides "
                f"{'/'.join(ENV_OPTIONS['forearm_dofs'])}; these demonstrations were played "
                f"with {'/'.join(dofs)}: build the dataset with the planner"
            )
    policy, trainer = trained or train_bc(data, config, env_options, log)
    history: list[dict[str, Any]] = []
    for r in range(rounds):
        f1 = {}
        for rollout in labelled_rollouts(policy, songs, r, workers):
            if rollout.labels.shape[1] != data.y.shape[1]:
                raise ValueError(
                    f"the planner's actions have {rollout.labels.shape[1]} values, the "
                    f"demonstrations' {data.y.shape[1]}: DAgger needs demonstrations played "
                    "in the planner's environment"
                )
            data.extend(rollout.x, rollout.labels)
            f1[rollout.song] = rollout.f1
            say(
                f"DAgger round {r + 1}/{rounds}: {rollout.song} F1 {rollout.f1:.3f} "
                f"(+{len(rollout.x)} labelled steps)"
            )
        history.append({"round": r + 1, "f1": f1, "steps": len(data.x)})
        losses = trainer.fit(data.x, data.y, config.steps, log)
        policy = trainer.policy(data.features, env_options or {})
        policy.info = {"steps": len(data.x), "final_loss": float(np.mean(losses[-100:]))}
    return policy, history


# ----------------------------------------------------------------------------- files


def save_policy(policy: BCPolicy, out: str | Path, extra: Mapping[str, Any] | None = None) -> Path:
    """Write ``policy`` to the folder ``out`` (replaced whole if it exists)."""
    net = policy.net
    arrays: dict[str, np.ndarray] = {"mean": net.mean, "std": net.std}
    for i, (w, b) in enumerate(net.layers):
        arrays[f"W{i}"], arrays[f"b{i}"] = w, b
    meta = {
        "format": FORMAT,
        "version": VERSION,
        "features": policy.features.to_dict(),
        "layers": len(net.layers),
        "activation": net.activation_name,
        "env_options": {
            k: list(v) if isinstance(v, tuple) else v for k, v in policy.env_options.items()
        },
        "info": {**policy.info, **(extra or {})},
    }
    out = Path(out)
    with atomic_dir(out) as tmp:
        np.savez(tmp / WEIGHTS_FILE, allow_pickle=False, **arrays)
        (tmp / CONFIG_FILE).write_text(json.dumps(meta, indent=2, default=_json) + "\n")
    return out


def _json(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple | set):
        return list(value)
    raise TypeError(f"not JSON: {type(value).__name__}")


def load_policy(folder: str | Path) -> BCPolicy:
    """The policy saved in ``folder`` by :func:`save_policy`.

    Raises:
        FileNotFoundError: no such folder, or not a behaviour-cloning policy.
        ValueError: a damaged or unknown file.
    """
    folder = Path(folder)
    if not (folder / CONFIG_FILE).is_file():
        raise FileNotFoundError(f"{folder} holds no behaviour-cloning policy (no {CONFIG_FILE})")
    try:
        meta = json.loads((folder / CONFIG_FILE).read_text())
        if meta.get("format") != FORMAT or meta.get("version") != VERSION:
            raise ValueError(f"unknown format {meta.get('format')} v{meta.get('version')}")
        with np.load(folder / WEIGHTS_FILE, allow_pickle=False) as z:
            layers = [(z[f"W{i}"], z[f"b{i}"]) for i in range(int(meta["layers"]))]
            mean, std = z["mean"], z["std"]
        features = Features.from_dict(meta["features"])
    except (
        OSError,
        KeyError,
        TypeError,
        json.JSONDecodeError,
        ValueError,
        EOFError,
        zipfile.BadZipFile,
    ) as exc:
        raise ValueError(f"{folder} is not a readable behaviour-cloning policy ({exc})") from None
    net = NumpyMLP(layers, mean, std, meta["activation"])
    if net.obs_dim != features.dim:
        raise ValueError(
            f"{folder}: the network reads {net.obs_dim} values, features give {features.dim}"
        )
    options = {k: tuple(v) if isinstance(v, list) else v for k, v in meta["env_options"].items()}
    return BCPolicy(features, net, options, meta.get("info", {}))


# ----------------------------------------------------------------------------- evaluation


def play_song_episode(
    policy: BCPolicy, env: MultiSongEnv, index: int, seed: int = 0
) -> dict[str, Any]:
    """One episode of song ``index`` of a :class:`pianist.env.multi_song.MultiSongEnv` played
    by ``policy``: its key precision, recall and F1, the song's name (``song``) and the
    real-time factor (``rtf``, simulated seconds per wall-clock second)."""
    import time

    from pianist.env.handle import control_handle
    from pianist.eval.metrics import precision_recall_f1

    obs, info = env.reset(seed=seed, options={"song": index})
    pressed, goal = [], []
    start = time.perf_counter()
    done = False
    while not done:
        obs, _, terminated, truncated, step_info = env.step(policy.act(obs))
        pressed.append(step_info["active_keys"])
        goal.append(step_info["goal_keys"])
        done = terminated or truncated
    wall = time.perf_counter() - start
    seconds = len(goal) * control_handle(env).control_timestep_s
    metrics = precision_recall_f1(np.array(pressed), np.array(goal))
    return {**metrics, "song": str(info["song"]), "rtf": seconds / max(wall, 1e-9)}


def evaluate_multi_song(
    policy: BCPolicy, env: MultiSongEnv, episodes: int = 1, seed: int = 0
) -> dict[str, list[float]]:
    """Play every song of a :class:`pianist.env.multi_song.MultiSongEnv` ``episodes`` times
    with ``policy`` (seeds ``seed``, ``seed + 1``, ...); returns song -> the F1 of each of its
    episodes. Songs are taken in turn, not drawn: a draw may miss a song, and a deterministic
    policy's episodes of one song repeat."""
    policy.features.check(env.observation_space)
    scores: dict[str, list[float]] = {}
    for i in range(episodes):
        for index in range(len(env.songs)):
            row = play_song_episode(policy, env, index, seed + i)
            scores.setdefault(row["song"], []).append(row["f1"])
    return scores
