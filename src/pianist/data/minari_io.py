"""Writing recorded episodes as a Farama Minari dataset, and reading one back.

A dataset is written whole or not at all: it is built with Minari's own
``create_dataset_from_buffers`` in a hidden staging root beside the final one, then renamed
into place, so ``minari.load_dataset`` never meets half a dataset. Minari is imported inside
the functions (the optional ``data`` extra).

Where Minari keeps things (version 0.5): per step, ``observations`` (a dict, T + 1 rows, the
reset's first), ``actions``, ``rewards``, ``terminations``, ``truncations`` and ``infos`` (T
rows here, aligned with the actions); per episode, the metadata of ``episode.json`` as HDF5
attributes (scalars; the provenance as JSON text); for the dataset, the ``pianist`` entry of
its metadata (every song's provenance, the build's settings, per-episode F1).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import warnings
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from pianist.data.record import EpisodeRecord

ENV_VAR = "MINARI_DATASETS_PATH"
_STAGING_PREFIX = ".pianist-staging-"
# Episode metadata kept as HDF5 attributes: scalars only (the rest is in the dataset's).
_EPISODE_SCALARS = (
    "song",
    "song_ref",
    "controller",
    "noise",
    "seed",
    "physics",
    "precision",
    "recall",
    "f1",
    "sustain_f1",
    "steps",
    "seconds",
    "return",
    "control_timestep_s",
)


def default_root() -> Path:
    """Minari's own datasets folder: ``$MINARI_DATASETS_PATH``, else ``~/.minari/datasets``."""
    configured = os.environ.get(ENV_VAR)
    return Path(configured) if configured else Path.home() / ".minari" / "datasets"


def check_dataset_id(dataset_id: str) -> None:
    """Refuse an id Minari would not accept: ``(namespace/)name-vN`` with letters, digits,
    ``-`` and ``_`` (e.g. ``pianist/open-etude-12-planner-v0``).

    Raises:
        ValueError: the id is malformed or has no version.
    """
    from minari.dataset.minari_dataset import DATASET_ID_RE

    match = DATASET_ID_RE.fullmatch(dataset_id)
    if match is None or match.group("version") is None:
        raise ValueError(
            f"dataset id {dataset_id!r} is not a Minari id: use (NAMESPACE/)NAME-vN with "
            "letters, digits, - and _ (e.g. pianist/open-etude-12-planner-v0)"
        )


def dataset_dir(dataset_id: str, root: Path) -> Path:
    """The folder of dataset ``dataset_id`` under ``root`` (Minari's layout)."""
    return root / dataset_id


@contextmanager
def datasets_root(root: Path) -> Iterator[None]:
    """Point Minari at ``root`` (``$MINARI_DATASETS_PATH``) inside the block only."""
    before = os.environ.get(ENV_VAR)
    os.environ[ENV_VAR] = str(root)
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(ENV_VAR, None)
        else:
            os.environ[ENV_VAR] = before


def write_dataset(
    dataset_id: str,
    records: Iterable[EpisodeRecord],
    root: Path,
    *,
    algorithm_name: str,
    description: str,
    metadata: dict[str, Any],
) -> Path:
    """Write ``records`` (one at a time: only one episode is in memory) as Minari dataset
    ``dataset_id`` under ``root`` and return its folder.

    Every episode must have the first one's observation and action spaces.

    Args:
        metadata: JSON-ready facts stored as the dataset metadata's ``pianist`` entry.
    Raises:
        ValueError: a bad id, an existing dataset, no episodes, or episodes whose spaces differ.
    """
    import minari
    from minari.data_collector.episode_buffer import EpisodeBuffer
    from minari.namespace import create_namespace, list_local_namespaces
    from minari.serialization import deserialize_space

    check_dataset_id(dataset_id)
    final = dataset_dir(dataset_id, root)
    if final.exists():
        raise ValueError(
            f"dataset {dataset_id} already exists in {root}: choose another NAME (a new "
            "version, -v1) or delete it first"
        )
    root.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(dir=root, prefix=_STAGING_PREFIX))
    try:
        dataset = None
        spaces: tuple[str, str] | None = None
        episodes_meta: list[dict[str, Any]] = []
        with datasets_root(staging):
            for record in records:
                these = (record.metadata["observation_space"], record.metadata["action_space"])
                if dataset is None:
                    spaces = these
                    with warnings.catch_warnings():
                        # Minari warns of every optional field left out (env spec, e-mail).
                        warnings.simplefilter("ignore", UserWarning)
                        dataset = minari.create_dataset_from_buffers(
                            dataset_id,
                            buffer=[],
                            env=None,
                            observation_space=deserialize_space(json.loads(these[0])),
                            action_space=deserialize_space(json.loads(these[1])),
                            algorithm_name=algorithm_name,
                            author="pianist",
                            description=description,
                            data_format="hdf5",
                            jpeg_encoding=False,
                        )
                elif these != spaces:
                    raise ValueError(
                        f"episode of {record.metadata['song']} has other observation or action "
                        "spaces than the first episode; one dataset needs one environment shape"
                    )
                dataset.storage.update_episodes([_buffer(record, EpisodeBuffer)])
                episodes_meta.append(record.metadata)
            if dataset is None:
                raise ValueError("no episodes to write")
            dataset.storage.update_episode_metadata([_episode_attrs(m) for m in episodes_meta])
            dataset.storage.update_metadata({"pianist": metadata})
        namespace = dataset_id.rpartition("/")[0]
        with datasets_root(root):
            if namespace and namespace not in list_local_namespaces():
                create_namespace(namespace, description="pianist demonstration datasets")
        final.parent.mkdir(parents=True, exist_ok=True)
        os.replace(staging / dataset_id, final)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return final


def _buffer(record: EpisodeRecord, buffer_type: Any) -> Any:
    return buffer_type(
        id=None,
        seed=int(record.metadata["seed"]),
        observations=record.observations,
        actions=record.actions,
        rewards=record.rewards,
        terminations=record.terminations,
        truncations=record.truncations,
        infos=record.infos,
    )


def _episode_attrs(metadata: dict[str, Any]) -> dict[str, Any]:
    attrs = {k: metadata[k] for k in _EPISODE_SCALARS if metadata.get(k) is not None}
    attrs["provenance"] = json.dumps(metadata["provenance"])
    return attrs


def load_dataset(dataset_id: str, root: str | os.PathLike[str] | None = None) -> Any:
    """``minari.load_dataset(dataset_id)`` with the datasets under ``root`` (default Minari's).

    Raises:
        ValueError: a malformed id, or a dataset whose files cannot be read.
        FileNotFoundError: no such dataset under the root.
    """
    import minari

    check_dataset_id(dataset_id)
    root = Path(root) if root is not None else default_root()
    if not (dataset_dir(dataset_id, root) / "data").is_dir():
        raise FileNotFoundError(f"no dataset {dataset_id} in {root}")
    with datasets_root(root):
        try:
            return minari.load_dataset(dataset_id)
        except (OSError, RuntimeError, ValueError, KeyError) as exc:  # HDF5 or JSON damage
            raise ValueError(
                f"dataset {dataset_id} in {root} cannot be read ({' '.join(str(exc).split())})"
            ) from None


def dataset_summary(dataset: Any) -> dict[str, Any]:
    """Episodes, steps, mean F1 and per-song rows of a loaded Minari dataset."""
    metas = list(dataset.storage.get_episode_metadata(dataset.episode_indices))
    songs: dict[str, list[float]] = {}
    for meta in metas:
        songs.setdefault(str(meta.get("song", "?")), []).append(float(meta.get("f1", np.nan)))
    f1 = [value for values in songs.values() for value in values]
    return {
        "dataset_id": dataset.id,
        "episodes": dataset.total_episodes,
        "steps": dataset.total_steps,
        "mean_f1": float(np.mean(f1)) if f1 else float("nan"),
        "songs": {
            name: {"episodes": len(values), "mean_f1": float(np.mean(values))}
            for name, values in songs.items()
        },
        "pianist": dataset.storage.metadata.get("pianist", {}),
    }


def dataset_setup(dataset: Any) -> tuple[dict[str, Any], list[str]]:
    """The environment options a loaded dataset's episodes were played in (its controller's
    declared ones and the physics) and its songs (as given to the build, in episode order).
    A policy trained on the dataset plays in those options."""
    from pianist.control.registry import build_controller
    from pianist.music import load_song

    metas = list(dataset.storage.get_episode_metadata(dataset.episode_indices))
    settings = dataset.storage.metadata.get("pianist", {}).get("settings", {})
    songs = list(dict.fromkeys(str(m.get("song_ref", m.get("song"))) for m in metas))
    controller = build_controller(settings.get("controller", "planner"))
    options: dict[str, Any] = dict(controller.env_options(load_song(songs[0])))
    physics = {str(m["physics"]) for m in metas if "physics" in m}
    if len(physics) == 1:
        options["physics"] = physics.pop()
    return options, songs
