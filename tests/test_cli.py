"""The pianist command line, run as users run it."""

import json
import os
import re
import subprocess
import sys
import time
import wave
from pathlib import Path

import mido
import numpy as np
import pytest

from pianist.cli import main


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pianist.cli", *args], capture_output=True, text=True, timeout=300
    )


def test_help_lists_subcommands():
    result = run("--help")
    assert result.returncode == 0
    for name in ("songs", "info", "play", "import-pig"):
        assert name in result.stdout


def test_songs_lists_builtins(capsys):
    assert main(["songs"]) == 0
    out = capsys.readouterr().out
    assert "twinkle-twinkle" in out and "c-major-chords" in out


def test_songs_explains_its_columns(capsys):
    assert main(["songs", "--suite", "debug"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].split() == ["name", "suite", "s", "notes", "n/s", "span", "poly"]
    legend = lines[-1]
    for text in ("s: duration in seconds", "n/s: notes per second", "span: widest hand span"):
        assert text in legend
    assert "semitones" in legend and "poly: most notes sounding at once" in legend


def test_info_describes_a_song(capsys):
    assert main(["info", "c-major-chords"]) == 0
    out = capsys.readouterr().out
    assert "notes:      16" in out and "81 frames" in out


def test_play_writes_metrics_midi_and_actions(tmp_path, capsys):
    out = tmp_path / "run"
    assert _play_zero(out) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    for key in ("precision", "recall", "f1", "sustain_f1", "steps", "seconds"):
        assert key in metrics
    assert metrics["steps"] == 81 and metrics["seconds"] == pytest.approx(4.05)
    # The errors by kind: the zero controller's hands sound none of the 16 notes.
    assert metrics["recall"] == 0.0 and metrics["notes"] == 16
    assert metrics["notes_never_share"] == 1.0 and metrics["lost_never_share"] == 1.0
    assert metrics["false_other_share"] == 0.0
    assert "missed: 100.0 % in notes never sounding" in capsys.readouterr().out
    actions = np.load(out / "actions.npy")
    assert actions.shape == (81, 39)
    mido.MidiFile(out / "performance.mid")  # a readable MIDI file
    # Replaying the saved actions reproduces the same scores.
    again = tmp_path / "again"
    assert (
        main(
            [
                "play",
                "c-major-chords",
                "--controller",
                f"replay:{out / 'actions.npy'}",
                "--out",
                str(again),
                "--physics",
                "fast",
            ]
        )
        == 0
    )
    replayed = json.loads((again / "metrics.json").read_text())
    assert replayed["f1"] == metrics["f1"] and replayed["return"] == metrics["return"]


def test_a_planner_run_replays_in_the_scene_it_was_recorded_in(tmp_path):
    out, again = tmp_path / "planned", tmp_path / "again"
    song = ["play", "c-major-chords", "--physics", "fast", "--no-audio"]
    assert main([*song, "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    # The planner declared the forearm height slide: 41 action dimensions, not the paper's 39.
    assert metrics["env_options"]["forearm_dofs"] == ["tx", "ty", "tz"]
    assert np.load(out / "actions.npy").shape == (81, 41)
    replay = ["--controller", f"replay:{out / 'actions.npy'}", "--out", str(again)]
    assert main([*song, *replay]) == 0
    replayed = json.loads((again / "metrics.json").read_text())
    assert replayed["f1"] == metrics["f1"] and replayed["return"] == metrics["return"]
    assert replayed["env_options"]["forearm_dofs"] == ["tx", "ty", "tz"]
    # A contradicting explicit choice is refused in one line.
    result = run("play", "c-major-chords", "--physics", "faithful", *replay)
    assert result.returncode == 1 and "physics='fast'" in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("make_input", "message"),
    [
        (lambda d: "no-such-song", "unknown song"),
        (lambda d: str(d / "missing.mid"), "not found"),
        (lambda d: _write(d / "empty.mid", b""), "empty"),
        (lambda d: _write(d / "text.mid", b"hello, not midi at all"), "not a MIDI file"),
    ],
)
def test_bad_input_gives_one_line_and_exit_1(tmp_path, make_input, message):
    result = run("play", make_input(tmp_path), "--out", str(tmp_path / "o"))
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pianist: error:")
    assert message in lines[0]
    assert "Traceback" not in result.stderr


def test_out_of_range_notes_are_refused(tmp_path):
    path = tmp_path / "low.mid"
    midi = mido.MidiFile()
    track = mido.MidiTrack()
    track += [
        mido.Message("note_on", note=10, velocity=80, time=0),
        mido.Message("note_off", note=10, velocity=0, time=480),
    ]
    midi.tracks.append(track)
    midi.save(path)
    result = run("info", str(path))
    assert result.returncode == 1 and "pianist: error:" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_play_leaves_out_of_range_notes_out_when_told(tmp_path, capsys):
    path = tmp_path / "piccolo.mid"
    track = mido.MidiTrack()
    for pitch in (60, 64, 67, 110):  # MIDI 110 is above the piano's top C (108)
        track += [
            mido.Message("note_on", note=pitch, velocity=80, time=0),
            mido.Message("note_off", note=pitch, velocity=0, time=240),
        ]
    midi = mido.MidiFile()
    midi.tracks.append(track)
    midi.save(path)
    args = ["play", str(path), "--no-audio", "--out", str(tmp_path / "o")]
    assert main(args) == 1
    assert "--out-of-range drop" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
    assert main([*args, "--out-of-range", "drop"]) == 0
    metrics = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert metrics["f1"] > 0.5  # the three notes in range, one after the other
    # `info` describes it the same way (the error names the option it has too).
    assert main(["info", str(path)]) == 1
    assert main(["info", str(path), "--out-of-range", "drop"]) == 0
    assert "notes:      3" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args",
    [
        ["play", "c-major-chords", "--controller", "zero"],
        ["eval", "/no/such/run", "c-major-chords"],
        ["dataset", "build", "--songs", "c-major-chords", "--out", "t/x-v0"],
        ["sweep", "--songs", "c-major-chords"],
    ],
)
def test_a_negative_seed_is_one_line_before_anything_runs(tmp_path, capsys, args):
    flag = "--seeds" if args[0] == "sweep" else "--seed"
    out = ["--root", str(tmp_path)] if args[0] == "dataset" else ["--out", str(tmp_path / "o")]
    assert main([*args, *out, flag, "-1"]) == 1
    err = capsys.readouterr().err
    assert err.strip().splitlines() == [f"pianist: error: {flag} must be >= 0, not -1"]
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["play", "c-major-chords", "--controller", "bogus"], "policy:RUN_DIR, bc:DIR"),
        (["play", "c-major-chords", "--controller", "policy:"], "needs a path: policy:RUN_DIR"),
        (["play", "c-major-chords", "--controller", "replay:"], "needs a path"),
        (["train", "c-major-chords", "--preset", "bogus"], "choose from practice, "),
    ],
)
def test_wrong_names_list_every_choice(tmp_path, capsys, args, message):
    assert main([*args, "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_recorded_actions_replay_only_on_their_own_song(tmp_path, capsys):
    recorded = tmp_path / "twinkle"
    args = ["--controller", "zero", "--physics", "fast", "--no-audio"]
    assert main(["play", "twinkle-twinkle", *args, "--out", str(recorded)]) == 0
    replay = ["--controller", f"replay:{recorded / 'actions.npy'}", "--no-audio"]
    assert main(["play", "c-major-chords", *replay, "--out", str(tmp_path / "o")]) == 1
    assert "replay them on the song" in capsys.readouterr().err
    text = tmp_path / "text.npy"
    text.write_text("not an array")
    replay = ["--controller", f"replay:{text}", "--out", str(tmp_path / "o")]
    assert main(["play", "c-major-chords", *replay]) == 1
    assert "is not a .npy array of actions" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_damaged_key_record_fails_the_report_in_one_line(tmp_path, capsys):
    out = tmp_path / "run"
    assert _play_zero(out, "--no-audio") == 0
    for damaged in (b"", b"PK\x03\x04 cut short"):
        (out / "keys.npz").write_bytes(damaged)
        assert main(["report", str(out)]) == 1
        err = capsys.readouterr().err
        assert "not a readable key record" in err and len(err.strip().splitlines()) == 1


def test_a_suite_not_imported_fails_before_its_table(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("PIANIST_PIG", str(tmp_path))  # no PIG pieces there
    assert main(["songs", "--suite", "etude-12"]) == 1
    captured = capsys.readouterr()
    assert captured.out == "" and "import-pig" in captured.err


def test_piping_into_head_ends_quietly():
    command = f"{sys.executable} -m pianist.cli songs --suite all | head -1"
    result = subprocess.run(command, shell=True, capture_output=True, text=True, timeout=120)
    assert result.stdout.split()[:2] == ["name", "suite"]
    assert result.stderr == ""  # no "Broken pipe" error once head has its line


def test_eval_of_a_file_says_it_is_not_a_run(tmp_path, capsys):
    path = tmp_path / "notes.txt"
    path.write_text("x")
    assert main(["eval", str(path), "c-major-chords"]) == 1
    assert "is a file, not a training run" in capsys.readouterr().err


def test_unwritable_output_directory(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    result = run("play", "c-major-chords", "--out", str(blocker / "sub"))
    assert result.returncode == 1 and "output directory" in result.stderr


def test_failed_run_keeps_previous_results(tmp_path):
    out = tmp_path / "run"
    assert _play_zero(out) == 0
    before = (out / "metrics.json").read_bytes()
    bad = tmp_path / "short.npy"
    np.save(bad, np.zeros((3, 39)))
    assert (
        main(
            [
                "play",
                "c-major-chords",
                "--controller",
                f"replay:{bad}",
                "--out",
                str(out),
                "--physics",
                "fast",
            ]
        )
        == 1
    )
    assert (out / "metrics.json").read_bytes() == before
    assert not list(out.glob(".*.tmp"))


def test_a_run_replaces_the_previous_one_whole(tmp_path):
    out = tmp_path / "run"
    assert _play_zero(out) == 0
    assert (out / "performance.wav").is_file() and (out / "score.wav").is_file()
    assert _play_zero(out, "--no-audio") == 0
    # No file of the earlier run is left beside the new one's.
    names = sorted(p.name for p in out.iterdir())
    assert names == ["actions.npy", "keys.npz", "metrics.json", "performance.mid", "pianoroll.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no temporary left


def test_a_folder_holding_other_files_is_refused(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("precious")
    result = run("play", "c-major-chords", "--controller", "zero", "--out", str(out))
    assert result.returncode == 1 and "holds other files" in result.stderr, result.stderr
    assert (out / "thesis.tex").read_text() == "precious" and len(list(out.iterdir())) == 1


def _play_zero(out: Path, *extra: str) -> int:
    """``pianist play c-major-chords`` with the zero controller on the fast preset."""
    args = ["play", "c-major-chords", "--controller", "zero", "--physics", "fast"]
    return main([*args, "--out", str(out), *extra])


def _write(path: Path, data: bytes) -> str:
    path.write_bytes(data)
    return str(path)


def test_play_writes_audio_pianoroll_and_video(tmp_path):
    import imageio_ffmpeg

    out = tmp_path / "media"
    args = ["play", "c-major-chords", "--controller", "zero", "--physics", "fast"]
    # Without antialiasing (the report's test renders the default, with it).
    args += ["--out", str(out), "--video", "--no-antialias", "--fps", "10", "--size", "64", "96"]
    result = run(*args)
    assert result.returncode == 0, result.stderr
    for name in ("metrics.json", "performance.mid", "actions.npy", "pianoroll.png"):
        assert (out / name).stat().st_size > 0
    with wave.open(str(out / "score.wav")) as score:
        # The score (4 s) plus the synthesiser's release tail, at 44.1 kHz.
        assert score.getframerate() == 44100 and score.getnframes() / 44100 >= 4.0
    with wave.open(str(out / "performance.wav")) as performance:
        assert performance.getnframes() / 44100 >= 81 * 0.05
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(out / "performance.mp4"))
    assert frames == 41  # 4.05 s at 10 fps, both ends included
    probe = subprocess.run(
        [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(out / "performance.mp4")],
        capture_output=True,
        text=True,
    )
    assert "Audio: aac" in probe.stderr and "64x96" not in probe.stderr
    assert "96x64" in probe.stderr  # ffmpeg reports width x height


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--soundfont", "/no/such/font.sf2"], "soundfont not found"),
        (["--soundfont", "/tmp"], "is a folder, not a .sf2/.sf3 file"),
        (["--video", "--camera", "ceiling"], "unknown camera"),
        (["--video", "--size", "63", "64"], "even"),
        (["--video", "--falling-notes", "--size", "16", "100"], "height of 32 or more"),
    ],
)
def test_bad_media_options_fail_before_playing(tmp_path, extra, message):
    out = tmp_path / "o"
    result = run("play", "c-major-chords", "--controller", "zero", "--out", str(out), *extra)
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], result.stderr
    assert not out.exists()  # a refused command creates nothing


def test_corrupt_soundfont_is_refused(tmp_path):
    font = tmp_path / "bad.sf2"
    font.write_bytes(b"RIFF not really a soundfont")
    result = run("play", "c-major-chords", "--out", str(tmp_path / "o"), "--soundfont", str(font))
    assert result.returncode == 1 and "soundfont" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_unfingered_midi_is_fingered_automatically_unless_file_is_asked(tmp_path):
    path = tmp_path / "plain.mid"
    midi = mido.MidiFile()
    track = mido.MidiTrack()
    track += [
        mido.Message("note_on", note=60, velocity=80, time=0),
        mido.Message("note_off", note=60, velocity=0, time=480),
    ]
    midi.tracks.append(track)
    midi.save(path)
    result = run("play", str(path), "--out", str(tmp_path / "o"), "--fingering", "file")
    assert result.returncode == 1 and "no finger" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    out = tmp_path / "auto"
    result = run("play", str(path), "--out", str(out), "--physics", "fast", "--no-audio")
    assert result.returncode == 0, result.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["fingering"] == "auto" and metrics["controller"] == "planner"


def _midi(path, tracks):
    """A type-1 MIDI file with one track per (name, pitches), one note per beat."""
    midi = mido.MidiFile(type=1)
    for name, pitches in tracks:
        track = mido.MidiTrack([mido.MetaMessage("track_name", name=name)])
        for pitch in pitches:
            track += [
                mido.Message("note_on", note=pitch, velocity=80, time=0),
                mido.Message("note_off", note=pitch, velocity=0, time=480),
            ]
        midi.tracks.append(track)
    midi.save(path)
    return str(path)


def test_info_says_where_the_hands_come_from(tmp_path, capsys):
    named = _midi(tmp_path / "named.mid", [("Right Hand", (72, 76)), ("Left Hand", (48, 52))])
    assert main(["info", named]) == 0
    out = capsys.readouterr().out
    assert "hands:      left, right (from the MIDI file, by track name: 'Right Hand' right, " in out
    assert "unknown" not in out
    assert "fingering:  0% of notes in the file (play estimates the rest" in out
    single = _midi(tmp_path / "single.mid", [("Piano", (60, 62, 64))])
    assert main(["info", single]) == 0
    out = capsys.readouterr().out
    assert "hands:      right (estimated: the file does not tell the two hands apart)" in out
    # One hand named, no other: not "names none" (the single group is placed by register).
    alone = _midi(tmp_path / "alone.mid", [("Left Hand", (72, 76))])
    assert main(["info", alone]) == 0
    assert "(estimated: the file does not tell the two hands apart)" in capsys.readouterr().out
    assert main(["info", "c-major-chords"]) == 0
    assert "hands:      left, right\n" in capsys.readouterr().out


def test_songs_lists_the_open_library_with_difficulty(capsys):
    assert main(["songs", "--suite", "open-etude-12"]) == 0
    rows = capsys.readouterr().out.strip().splitlines()[1:-1]  # no header, no legend
    assert len(rows) == 12
    for row in rows:
        fields = row.split()
        assert fields[1] == "open-etude-12" and float(fields[2]) >= 20.0


def test_import_pig_from_a_wrong_directory_is_one_line(tmp_path):
    result = run("import-pig", str(tmp_path / "nowhere"), "--dest", str(tmp_path / "d"))
    assert result.returncode == 1
    assert len(result.stderr.strip().splitlines()) == 1 and "pianist: error:" in result.stderr


def test_play_with_the_mpc_records_its_speed(tmp_path):
    out = tmp_path / "mpc"
    spec = "mpc:paper,num_samples=3,iterations=1"
    args = ["play", "c-major-chords", "--controller", spec, "--physics", "fast"]
    assert main([*args, "--out", str(out), "--no-audio"]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["mpc_steps"] == 81 and metrics["mpc_realtime_factor"] > 0
    assert metrics["controller_options"]["num_samples"] == 3


def test_bad_mpc_spec_is_one_line(tmp_path):
    result = run("play", "c-major-chords", "--controller", "mpc:paper,num_samples=-1")
    assert result.returncode == 1 and len(result.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_train_resume_eval_and_play_a_policy(tmp_path):
    run_dir = tmp_path / "run"
    args = ["train", "c-major-chords", "--preset", "fast-small", "--steps", "120"]
    assert main([*args, "--out", str(run_dir), "--no-progress"]) == 0
    assert (run_dir / "config.json").is_file() and (run_dir / "log.jsonl").is_file()
    # Resuming continues to a larger total and says from where.
    result = run("train", "--resume", str(run_dir), "--steps", "160")
    assert result.returncode == 0, result.stderr
    assert not result.stderr.strip(), "a progress bar was drawn into a pipe"
    assert "resumed" in result.stdout and "step 160" in result.stdout
    # The best evaluated policy is kept beside the run and plays like one.
    assert "best evaluation: F1" in result.stdout and (run_dir / "best").is_dir()
    best = ["eval", str(run_dir / "best"), "c-major-chords", "--out", str(tmp_path / "best")]
    assert main(best) == 0
    assert main(["eval", str(run_dir), "c-major-chords", "--out", str(tmp_path / "ev")]) == 0
    metrics = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    assert metrics["checkpoint_step"] == 160 and metrics["preset"] == "fast-small"
    # Trained on the fast physics, evaluated (during training, and here unless told) on the
    # faithful one, the rest of the task as trained; asked for, on its training physics.
    assert metrics["physics"] == "faithful" and metrics["trained_physics"] == "fast"
    other = ["eval", str(run_dir), "c-major-chords", "--physics", "fast"]
    assert main([*other, "--out", str(tmp_path / "fast")]) == 0
    moved = json.loads((tmp_path / "fast" / "metrics.json").read_text())
    assert moved["physics"] == moved["trained_physics"] == "fast"
    assert moved["env_options"]["hands"] == metrics["env_options"]["hands"]
    out = tmp_path / "play"
    args = ["play", "c-major-chords", "--controller", f"policy:{run_dir}", "--no-audio"]
    assert main([*args, "--out", str(out)]) == 0
    assert json.loads((out / "metrics.json").read_text())["steps"] == 81


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["train", "c-major-chords", "--preset", "nope"], "unknown preset"),
        (["train", "c-major-chords", "--steps", "0"], "--steps must be at least 1"),
        (["train", "c-major-chords", "--minutes", "0"], "--minutes must be a positive number"),
        (["train", "c-major-chords", "--minutes", "nan"], "--minutes must be a positive number"),
        (["train", "--resume", "/no/such/run", "--steps", "-5"], "--steps must be at least 1"),
        (["train"], "give a SONG"),
        (["eval", "/no/such/run", "c-major-chords"], "run directory not found"),
        (["play", "c-major-chords", "--controller", "policy:/no/such/run"], "not found"),
    ],
)
def test_training_commands_fail_in_one_line(tmp_path, args, message):
    result = run(*args)
    assert result.returncode == 1 and message in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_a_lead_in_delays_the_song_and_scores_its_steps_alone(tmp_path):
    out = tmp_path / "lead"
    assert _play_zero(out, "--initial-buffer-s", "0.5") == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["steps"] == 81 + 10 and metrics["lead_in_steps"] == 10
    assert metrics["env_options"]["initial_buffer_s"] == 0.5
    # The zero controller presses nothing: the silent lead-in scores, the song does not.
    assert metrics["song_f1"] == pytest.approx(0.0) and metrics["f1"] == pytest.approx(10 / 91)
    with wave.open(str(out / "score.wav")) as score:
        rate = score.getframerate()
        samples = np.frombuffer(score.readframes(score.getnframes()), dtype=np.int16)
    samples = samples.reshape(-1, score.getnchannels()).astype(float)
    # The score starts with the lead-in's silence, like the performance.
    assert np.abs(samples[: int(0.45 * rate)]).max() == 0
    assert np.abs(samples[int(0.5 * rate) : int(0.7 * rate)]).max() > 1000


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--initial-buffer-s", "-1"], "must be >= 0"),
        (["--initial-buffer-s", "0.5", "--controller", "policy:/no/run"], "trained policy"),
    ],
)
def test_a_bad_lead_in_is_one_line(tmp_path, extra, message):
    result = run("play", "c-major-chords", "--out", str(tmp_path / "o"), *extra)
    assert result.returncode == 1 and message in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_simulation_warnings_do_not_leave_a_log_in_the_checkout(request):
    """MuJoCo appends its warnings to MUJOCO_LOG.TXT in the working directory; the suite runs
    in a scratch one (conftest.py), so the log never lands where pytest was started."""
    import mujoco

    started_in = Path(request.config.invocation_params.dir)
    assert Path.cwd() != started_in
    had_log = (started_in / "MUJOCO_LOG.TXT").exists()
    xml = '<mujoco><worldbody><body><freejoint/><geom size=".1"/></body></worldbody></mujoco>'
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[:] = np.nan
    mujoco.mj_step(model, data)  # "Nan, Inf or huge value in QVEL": written to the log
    assert (Path.cwd() / "MUJOCO_LOG.TXT").is_file()
    assert (started_in / "MUJOCO_LOG.TXT").exists() == had_log


@pytest.mark.parametrize("command", ["play", "info", "train", "eval", "import-pig"])
def test_help_names_the_song_and_states_each_default_once(command):
    result = subprocess.run(
        [sys.executable, "-m", "pianist.cli", command, "--help"],
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "COLUMNS": "200"},
    )
    assert result.returncode == 0
    usage = result.stdout.splitlines()[0]
    assert "STR" not in usage and "PATH" not in usage.split("]")[-1]
    if command != "import-pig":
        assert usage.endswith("SONG") or " SONG " in usage
    # One block per option: each says its default once, and never "(default: None)".
    blocks = re.split(r"│ (?=--)", result.stdout)
    for block in blocks:
        assert block.count("(default") <= 1, block
    assert "(default: None)" not in result.stdout


def test_train_stops_when_its_time_budget_runs_out(tmp_path, capsys):
    # 3 seconds of a run of 100k steps: it stops at the end of the episode in which the
    # budget runs out, checkpointed, with its evaluated policy kept.
    run_dir = tmp_path / "run"
    args = ["train", "c-major-chords", "--preset", "fast-small", "--steps", "100000"]
    start = time.perf_counter()
    assert main([*args, "--minutes", "0.05", "--out", str(run_dir), "--no-progress"]) == 0
    assert time.perf_counter() - start < 90
    state = json.loads((run_dir / "checkpoints" / "latest.json").read_text())
    assert 0 < state["step"] < 100_000 and state["step"] % 81 == 0  # whole episodes
    assert (run_dir / "best" / "checkpoints" / "latest.json").is_file()
    assert f"trained to step {state['step']}" in capsys.readouterr().out


def test_play_says_how_far_the_dynamics_are_from_a_scores_with_loudness(tmp_path, capsys):
    """A score whose velocities differ gets a dynamics line (and, played with every note
    struck, the default that plays them); a score of one velocity gets none."""
    args = ["--physics", "fast", "--seconds", "2"]
    assert main(["play", "voiced-melody", "--out", str(tmp_path / "a"), *args]) == 0
    out = capsys.readouterr().out
    assert "dynamics: velocity error" in out and "plays the soft notes softly" not in out
    struck = ["--controller", "planner:push_below_velocity=0"]
    assert main(["play", "voiced-melody", "--out", str(tmp_path / "b"), *struck, *args]) == 0
    out = capsys.readouterr().out
    assert "dynamics: velocity error" in out
    assert "the default, 80, plays the soft notes softly" in out
    assert main(["play", "c-major-chords", "--out", str(tmp_path / "c"), *args]) == 0
    assert "dynamics:" not in capsys.readouterr().out
