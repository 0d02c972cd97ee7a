"""``pianist bc``: behaviour cloning (and DAgger) from a demonstration dataset."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import tyro

from pianist.cli.common import CliError, check_seed, out, prepare_dir, require_jax
from pianist.files import check_replaceable_dir


@dataclass(frozen=True)
class BCTrain:
    """Train one policy for the songs of a Minari dataset by behaviour cloning (MSE on the
    actions), then optionally N rounds of DAgger: the policy plays the songs and the planner
    labels every state it visits (docs/bc.md). Play the result with --controller bc:OUT."""

    dataset: str
    """The dataset id, e.g. pianist/open-etude-12-planner-v0 (pianist dataset build)."""
    out: Path
    """The policy's folder (an earlier policy there is replaced whole; a folder holding
    anything else is refused)."""
    root: Annotated[
        Path | None,
        tyro.conf.arg(metavar="PATH", help_behavior_hint="(default: Minari's datasets folder)"),
    ] = None
    """Where datasets are stored."""
    dagger_rounds: int = 0
    """DAgger rounds after behaviour cloning (each plays every song once)."""
    songs: Annotated[
        tuple[str, ...], tyro.conf.arg(help_behavior_hint="(default: the dataset's songs)")
    ] = ()
    """Songs DAgger plays."""
    hidden: tuple[int, ...] = (256, 256)
    """Hidden layer widths (the paper's: up to 1024)."""
    steps: int = 3000
    """Adam steps of behaviour cloning, and again of each DAgger round."""
    batch_size: int = 256
    """Demonstration steps per Adam step."""
    learning_rate: float = 1e-3
    """Adam's learning rate."""
    input_noise: float = 0.3
    """Std of the noise added to the standardised features of each minibatch (0: none)."""
    seed: int = 0
    """Seed of the weights and the minibatches."""
    workers: int = 1
    """Songs DAgger plays at once, each in its own process."""

    def run(self) -> None:
        import importlib.util

        require_jax()
        if importlib.util.find_spec("minari") is None:
            raise CliError("datasets need Minari: pip install 'pianist[data]' (minari[hdf5])")
        for name, value in (("--steps", self.steps), ("--batch-size", self.batch_size)):
            if value < 1:
                raise CliError(f"{name} must be >= 1, not {value}")
        if self.workers < 1:
            raise CliError(f"--workers must be >= 1, not {self.workers}")
        if self.dagger_rounds < 0:
            raise CliError(f"--dagger-rounds must be >= 0, not {self.dagger_rounds}")
        if not self.hidden or min(self.hidden) < 1:
            raise CliError(f"--hidden needs widths >= 1, not {list(self.hidden)}")
        if not (math.isfinite(self.input_noise) and self.input_noise >= 0):
            raise CliError(f"--input-noise must be a finite number >= 0, not {self.input_noise}")
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise CliError(f"--learning-rate must be a finite number > 0, not {self.learning_rate}")
        check_seed(self.seed)
        from pianist.agents import bc
        from pianist.data.minari_io import dataset_setup, load_dataset
        from pianist.music import load_song

        _check_policy_out(self.out, bc.CONFIG_FILE, bc.WEIGHTS_FILE)
        if self.dagger_rounds:
            for song in self.songs:  # before the cloning, not after it
                load_song(song, fingering="auto")

        dataset = load_dataset(self.dataset, self.root)
        options, songs = dataset_setup(dataset)
        songs = list(self.songs) or songs
        prepare_dir(self.out.parent)
        data = bc.demonstrations(bc.minari_episodes(dataset))
        config = bc.BCConfig(
            hidden_dims=self.hidden,
            learning_rate=self.learning_rate,
            batch_size=self.batch_size,
            steps=self.steps,
            input_noise=self.input_noise,
            seed=self.seed,
        )
        out(
            f"{self.dataset}: {len(data.x)} steps, {data.features.dim} features, "
            f"{data.y.shape[1]} actions; environment {options}"
        )
        policy, history = bc.dagger(
            data, songs, self.dagger_rounds, config, options, log=out, workers=self.workers
        )
        if not math.isfinite(policy.info["final_loss"]):
            raise CliError(
                f"training diverged (loss {policy.info['final_loss']}): nothing written; try a "
                "lower --learning-rate"
            )
        bc.save_policy(
            policy,
            self.out,
            {"dataset": self.dataset, "config": bc.config_dict(config), "dagger": history},
        )
        out(
            f"wrote {self.out} (final loss {policy.info['final_loss']:.5f}); "
            f"play it with: pianist play SONG --controller bc:{self.out}"
        )


def _check_policy_out(out: Path, *policy_files: str) -> None:
    """Refuse an ``--out`` that is not a folder of the policy's own: a file, the working
    folder or one above it, or a folder holding anything but an earlier policy's files."""
    here = Path.cwd().resolve()
    target = out.resolve()
    if target == here or target in here.parents:
        raise CliError(f"--out {out} is the working folder or above it; give a folder of its own")
    check_replaceable_dir(
        out,
        policy_files,
        error=lambda message: CliError(f"--out {message}"),
        advice="give a new folder or an earlier policy's",
    )


@dataclass(frozen=True)
class BCEval:
    """Play a behaviour-cloning policy on several songs in one multi-song environment (the
    same spaces for every song) and print each song's mean F1."""

    policy: tyro.conf.Positional[Annotated[Path, tyro.conf.arg(metavar="DIR")]]
    """The policy's folder (pianist bc train --out)."""
    songs: tuple[str, ...]
    """Songs to draw from (names or files)."""
    episodes: int = 1
    """Episodes per song (seeds --seed, --seed + 1, ...)."""
    seed: int = 0
    """Seed of the first episode of each song."""

    def run(self) -> None:
        if self.episodes < 1:
            raise CliError(f"--episodes must be >= 1, not {self.episodes}")
        check_seed(self.seed)
        from pianist.agents.bc import evaluate_multi_song, load_policy
        from pianist.env.multi_song import MultiSongEnv

        policy = load_policy(self.policy)
        env = MultiSongEnv(list(self.songs), **policy.env_options)
        try:
            scores = evaluate_multi_song(policy, env, self.episodes, self.seed)
        finally:
            env.close()
        out(f"{'song':40s} {'episodes':>8s} {'F1':>6s}")
        for song, values in sorted(scores.items()):
            out(f"{song:40s} {len(values):8d} {sum(values) / len(values):6.3f}")
        every = [v for values in scores.values() for v in values]
        out(f"{'mean over episodes':40s} {len(every):8d} {sum(every) / len(every):6.3f}")


@dataclass(frozen=True)
class BC:
    """Behaviour cloning and DAgger: one policy for many songs (train one, evaluate one)."""

    # OmitArgPrefixes: the subcommand's description is shown once, not again over its options.
    command: tyro.conf.OmitArgPrefixes[
        tyro.conf.OmitSubcommandPrefixes[
            Annotated[BCTrain, tyro.conf.subcommand("train")]
            | Annotated[BCEval, tyro.conf.subcommand("eval")]
        ]
    ]

    def run(self) -> None:
        self.command.run()
