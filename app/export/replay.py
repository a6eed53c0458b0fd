"""A replay folder any static web server shows: the recorded life of a run's final elite (and one
recorded implementation trial with its fault) drawn by the dashboard's views (app.views) on a
private viser server, recorded with viser's scene serializer, beside viser's bundled client.

The folder holds `replay.viser` (the recording), `index.html` (viser's client build, which plays
`?playbackPath=replay.viser` when opened without a query) and `README.txt`.
"""

from __future__ import annotations

import contextlib
import io
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import viser

import gnp
import sim
from app.brains.registry import family_of
from app.loop.recording import Trajectory
from app.phases.implementation import fault_text, faults
from app.phases.live import RobotSnapshot
from app.settings.arenas import arena_of
from app.store import Implementation, RunReader
from app.views.arena_view import ArenaView
from app.views.genome import genome_view
from app.views.graph_view import GraphView
from app.views.scene import aim_camera, scene_frame

RECORDING = "replay.viser"
MAX_FRAMES = 250
"""Frames per life at most (longer lives are subsampled): keeps the recording a few MB."""
CLIENT_BUILD = Path(viser.__file__).parent / "client" / "build"
PLAY_RECORDING = (
    "<script>if(!new URLSearchParams(location.search).has('playbackPath'))"
    "history.replaceState(null,'',location.pathname+'?playbackPath=" + RECORDING + "');</script>"
)


@dataclass(frozen=True)
class Life:
    """One recorded life to play: its robot, arena, trajectory row and fault."""

    caption: str
    cfg: gnp.GnpConfig
    individual: gnp.Population
    arena: sim.Arena
    lives: Trajectory
    row: int
    segment: int  # steps per episode (new start pose), 0: one episode
    control_period: float
    fault: sim.Fault | None = None


class _Visits:
    """The visits of a life, flattened, with where each step's visits end."""

    def __init__(self, trace: dict[str, np.ndarray], row: int) -> None:
        count = trace["count"][row].astype(np.int64)
        columns = [trace[f][row] for f in gnp.VISIT_FIELDS]
        self.rows = np.concatenate(
            [np.stack([c[t, : count[t]] for c in columns], 1) for t in range(len(count))]
        ).astype(np.int64)
        self.ends = np.cumsum(count)

    def until(self, t: int, recent: int) -> np.ndarray:
        end = int(self.ends[t])
        return self.rows[max(0, end - recent) : end]


def _snapshot(life: Life, visits: _Visits, t: int) -> RobotSnapshot:
    """What the dashboard would show after step t of the life."""
    lives, k = life.lives, life.row
    start = (t // life.segment) * life.segment if life.segment else 0
    reward = lives.reward[k]
    broken = np.zeros(sim.N_SENSORS, bool)
    if life.fault is not None and t + 1 >= life.fault.step:
        broken[list(life.fault.sensors)] = True
    seen = lives.observations[k, min(t + 1, len(reward) - 1)]
    recent = visits.until(t, GraphView.RECENT + 1)
    return RobotSnapshot(
        label=life.caption,
        method=life.cfg.method,
        t=t + 1,
        pose=lives.poses[k, t],
        true_readings=lives.readings[k, t],
        seen_readings=seen,
        broken=broken,
        fault_mode=life.fault.mode if life.fault is not None and broken.any() else None,
        trajectory=lives.poses[k, start : t + 1, :2],
        trajectory_reward=reward[start : t + 1],
        reward_steps=np.arange(start, t + 1),
        rewards=reward[start : t + 1],
        broken_counts=np.zeros(t + 1 - start, np.int64),
        fault_steps=(life.fault.step,) if life.fault is not None else (),
        visits=recent,
        current_node=int(recent[-1, 0]) if len(recent) else 0,
        epsilon=0.0,
        alpha=0.0,
        mean_reward=float(reward[: t + 1].mean()),
    )


class ReplayScene:
    """The dashboard's arena and graph views on a server, framed as the dashboard frames them."""

    def __init__(self, server: viser.ViserServer, arenas: list[sim.Arena]) -> None:
        self.server = server
        frame = scene_frame(arenas)
        self.arena = ArenaView(server, arenas[0], max_robots=1)
        self.graph = GraphView(server, frame.graph_origin, frame.width, frame.graph_height)
        self.caption = server.scene.add_label(
            "/replay/caption",
            "",
            position=(float(frame.xmin), float(frame.ymax + 0.03 * frame.width), 0.0),
            anchor="bottom-left",
        )
        aim_camera(server, frame, headroom=0.06)  # room for the caption

    def play(self, life: Life, recording: viser.infra.StateSerializer) -> int:
        """Record the life's frames (subsampled to MAX_FRAMES); returns the frames recorded."""
        steps = life.lives.poses.shape[1]
        stride = max(1, -(-steps // MAX_FRAMES))
        visits = _Visits(life.lives.trace, life.row)
        with self.server.atomic():
            self.arena.set_arena(life.arena)
            self.graph.set_genome(genome_view(life.cfg, life.individual))
        frames = list(range(0, steps, stride))
        if frames[-1] != steps - 1:
            frames.append(steps - 1)
        for t in frames:
            robot = _snapshot(life, visits, t)
            fault = ""
            if robot.broken.any():
                assert life.fault is not None
                fault = " · " + fault_text(life.fault.sensors, life.fault.mode, life.fault.step)
            with self.server.atomic():
                self.arena.update((robot,))
                self.graph.update(robot)
                self.caption.text = (
                    f"{life.caption} · step {t + 1}/{steps} · "
                    f"mean reward {robot.mean_reward:.3f}{fault}"
                )
            recording.insert_sleep(stride * life.control_period)
        return len(frames)


def _best(reader: RunReader, generation: int) -> tuple[gnp.GnpConfig, gnp.Population]:
    """The GNP config and a generation's best of a run with a node graph (`export_replay`
    refuses the others)."""
    family = family_of(reader.config)
    cfg = family.graph_config
    assert cfg is not None, f"{reader.path.name}: no node graph to replay"
    return cfg, family.best(reader, generation)


def _implementation_life(reader: RunReader, result: Implementation) -> Life:
    """Recorded trial 0 of an implementation phase, with its fault."""
    settings = result.settings
    seed = settings.seed if settings.seed is not None else reader.seed
    trial = int(result.recorded[0])
    scheduled = [
        f for f in faults(settings, seed, np.array([trial])) if f.robots is None or 0 in f.robots
    ]
    cfg, individual = _best(reader, result.generation)
    return Life(
        caption=f"implementation {result.name}, trial {trial} (start pose "
        f"{int(result.start_index[trial])})",
        cfg=cfg,
        individual=individual,
        arena=arena_of(settings.arena),
        lives=result.trials,
        row=0,
        segment=0,
        control_period=reader.config.training.control_period,
        fault=scheduled[0] if scheduled else None,
    )


def replay_lives(reader: RunReader) -> list[Life]:
    """The final elite's recorded life, then one implementation trial (one with a fault if any)."""
    elite = reader.elite()
    if elite is None:
        raise ValueError(f"{reader.path.name} has no recorded elite life")
    training = reader.config.training
    cfg, individual = _best(reader, -1)
    lives = [
        Life(
            caption=f"run {reader.path.stem}: final elite (generation "
            f"{reader.generations_done - 1}), {cfg.method} {cfg.judgment}",
            cfg=cfg,
            individual=individual,
            arena=arena_of(training.arena),
            lives=elite,
            row=0,
            segment=training.redraw_every,
            control_period=training.control_period,
        )
    ]
    results = [reader.implementation(name) for name in reader.implementation_names()]
    recorded = [r for r in results if len(r.recorded)]
    if recorded:
        faulted = [r for r in recorded if r.settings.broken_sensors or r.settings.break_count]
        lives.append(_implementation_life(reader, (faulted or recorded)[-1]))
    return lives


def write_replay(reader: RunReader, folder: Path) -> Path:
    """Record the replay of a finished run into `folder` (which must exist)."""
    lives = replay_lives(reader)
    # viser prints its address and "Server stopped" whatever `verbose` says; keep stdout clean.
    quiet = contextlib.redirect_stdout(io.StringIO())
    with quiet:
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        scene = ReplayScene(server, [life.arena for life in lives])
        recording = server.get_scene_serializer()
        for life in lives:
            scene.play(life, recording)
        (folder / RECORDING).write_bytes(recording.serialize())
    finally:
        with quiet:
            server.stop()
    for item in CLIENT_BUILD.iterdir():
        target = folder / item.name
        if item.is_dir():
            shutil.copytree(item, target)
        else:
            shutil.copy2(item, target)
    index = folder / "index.html"
    html = index.read_text(encoding="utf-8")
    head = html.index("<head>") + len("<head>")
    index.write_text(html[:head] + PLAY_RECORDING + html[head:], encoding="utf-8")
    (folder / "README.txt").write_text(
        f"Replay of run {reader.path.stem} (GNP Lab). Serve this folder with any static web "
        "server, e.g.\n\n    python -m http.server --bind 127.0.0.1 8000\n\nand open "
        "http://127.0.0.1:8000/ (index.html plays replay.viser). Opening index.html as a file "
        "does not work: browsers do not let a page read a file beside it.\n",
        encoding="utf-8",
    )
    return folder
