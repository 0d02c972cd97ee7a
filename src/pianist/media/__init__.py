"""Media made from episodes and songs: piano audio, MP4 videos, piano-roll plots.

Importing this package is cheap: the heavy libraries (tinysoundfont, mujoco, imageio-ffmpeg,
tqdm, matplotlib) are imported by the functions that use them. Rendering video needs an
offscreen OpenGL context: on a machine without a display set ``MUJOCO_GL=egl`` (or ``osmesa``)
before ``mujoco`` is first imported.
"""

from pianist.media.audio import (
    check_soundfont,
    default_soundfont,
    loudness_dbfs,
    normalise_loudness,
    stereo_comparison,
    synthesize_events,
    synthesize_song,
    write_wav,
)
from pianist.media.dynamics import episode_velocities, speed_to_velocity, strike_speeds
from pianist.media.errors import MediaError
from pianist.media.plots import pianoroll_counts, plot_pianoroll
from pianist.media.video import (
    check_video_options,
    frame_times,
    interpolate_qpos,
    key_colours,
    render_episode,
)

__all__ = [
    "MediaError",
    "check_soundfont",
    "check_video_options",
    "default_soundfont",
    "episode_velocities",
    "frame_times",
    "interpolate_qpos",
    "key_colours",
    "loudness_dbfs",
    "normalise_loudness",
    "pianoroll_counts",
    "plot_pianoroll",
    "render_episode",
    "speed_to_velocity",
    "stereo_comparison",
    "strike_speeds",
    "synthesize_events",
    "synthesize_song",
    "write_wav",
]
