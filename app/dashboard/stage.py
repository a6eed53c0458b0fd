"""What is on show: the robots, their arena and start pose, and how they play (no viser here).

A `Show` says what to put on the arena; the `Stage` turns it into a live session, steps it at
the chosen speed, starts a new life after T steps, and carries the noise and learning settings
over from one show to the next. The dashboard calls it under its lock; nothing here is
thread-safe by itself.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import sim
from app import store
from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.brains.registry import family_of
from app.dashboard.controls import DashboardInputError
from app.phases.live import LearningSettings, LiveSession, RobotSpec, checked_noise
from app.settings.config import RunConfig, TrainingSettings

MAX_STEPS_PER_ADVANCE = 50
"""A frame that comes late catches up at most this many steps (then the loop just slows)."""


@dataclass(frozen=True)
class Show:
    """What is on show: robots, arena, start pose, and where they came from.

    `runs` names the run each robot came from as the Runs tab lists it, and `sources` are their
    files (both parallel to `robots`; empty or None: an untrained individual): every panel of
    the page names the run of the robot it draws and reads its charts from its file."""

    title: str
    robots: tuple[RobotSpec, ...]
    arena: str
    start: int
    fault: tuple[int, tuple[int, ...], str] | None = None  # scheduled (step, sensors, mode)
    life: int = 0  # steps per life, as in training (then the next start pose); 0: endless
    control_period: float = sim.CONTROL_PERIOD_S  # simulated s per step, the run's setting
    runs: tuple[str, ...] = ()
    sources: tuple[Path | None, ...] = ()

    def origin(self, index: int) -> tuple[str, Path | None]:
        """(run name, run file) of robot `index` ("" and None where unknown)."""
        run = self.runs[index] if index < len(self.runs) else ""
        source = self.sources[index] if index < len(self.sources) else None
        return run, source


def run_robot(reader: store.RunReader, generation: int = -1) -> RobotSpec:
    """The best individual of a run's `generation` (negative: from the end), named after the
    run, of whichever brain family it is."""
    family = family_of(reader.config)
    return RobotSpec(reader.path.stem, family, family.best(reader, generation))


def random_show() -> Show:
    """An untrained random CS individual: what is on show when there is no run at all."""
    config = RunConfig(
        brain=GnpSettings(controller=ControllerSettings(method="CS")),
        training=TrainingSettings(population=2),
    )
    family = family_of(config)
    individual = family.take(family.first().individuals(), [0])
    return Show(
        "an untrained random CS individual",
        (RobotSpec("random", family, individual),),
        "training",
        0,
        life=1000,
    )


Listener = Callable[[Show, LiveSession], None]


class Stage:
    """The robots on show and how they play.

    Args:
        arenas: the arenas a show may use, by name (default: every shipped arena).
    """

    def __init__(self, arenas: Mapping[str, sim.Arena] | None = None) -> None:
        self.arenas = dict(arenas or {name: sim.load_arena(name) for name in sim.ARENA_NAMES})
        self.session: LiveSession | None = None
        self.show: Show | None = None
        self.speed = 30.0  # control steps per second of wall time
        self.playing = True
        self.new_lives = True  # a new life from the next start pose after the show's life T
        self.noise_sigma = 0.0
        self.learning = LearningSettings()
        self.selected = 0  # the robot whose graph and inspector are drawn
        self._owed = 0.0  # steps owed to the speed, carried from one advance to the next
        self._listeners: list[Listener] = []

    def on_staged(self, listener: Listener) -> None:
        """Call `listener(show, session)` whenever a show is put on the stage."""
        self._listeners.append(listener)

    @property
    def arena(self) -> str:
        """The arena on show (the training arena before any show)."""
        return self.show.arena if self.show is not None else "training"

    @property
    def start(self) -> int:
        """The start pose on show (0 before any show)."""
        return self.show.start if self.show is not None else 0

    @property
    def faults(self) -> tuple[tuple[int, ...], str] | None:
        """The sensors broken on show now and their mode (None: none broken)."""
        if self.session is None:
            return None
        robot = self.session.snapshot()[0]
        broken = tuple(int(i) for i in robot.broken.nonzero()[0])
        if not broken or robot.fault_mode is None:
            return None
        return broken, str(robot.fault_mode)

    def present(self, show: Show, keep_faults: bool = False) -> LiveSession:
        """Put `show` on the stage: a fresh live session with the current noise and learning
        (and, with `keep_faults`, the sensors broken on show now broken from its first step)."""
        if show.arena not in self.arenas:
            raise DashboardInputError(f"unknown arena {show.arena!r}")
        faults = self.faults if keep_faults else None
        session = LiveSession(
            self.arenas[show.arena],
            show.robots,
            start=show.start,
            seed=0,
            noise_sigma=self.noise_sigma,
            learning=self.learning,
            control_period=show.control_period,
        )
        if show.fault is not None:
            session.schedule_fault(*show.fault)
        if faults is not None:
            session.break_sensors(*faults)
        if self.selected >= len(show.robots):
            self.selected = 0
        self.session, self.show = session, show
        for listener in self._listeners:
            listener(show, session)
        return session

    def swap_in(
        self,
        title: str,
        robot: RobotSpec,
        life: int = 0,
        control_period: float = sim.CONTROL_PERIOD_S,
        run: str = "",
        source: Path | None = None,
    ) -> LiveSession:
        """Put another individual (of run `run`, file `source`) on show in the arena and from
        the start pose on show now."""
        return self.present(
            Show(
                title,
                (robot,),
                self.arena,
                self.start,
                life=life,
                control_period=control_period,
                runs=(run,),
                sources=(source,),
            )
        )

    @property
    def source(self) -> Path | None:
        """The run file of the robot whose graph is drawn (None: none, or nothing on show)."""
        return self.show.origin(self.selected)[1] if self.show is not None else None

    def select(self, index: int) -> None:
        """Draw the graph and inspector of robot `index` on show."""
        robots = self.show.robots if self.show is not None else ()
        if not 0 <= index < len(robots):
            raise DashboardInputError(f"robot must be in 1..{len(robots)}, got {index + 1}")
        self.selected = index
        if self.show is not None and self.session is not None:
            for listener in self._listeners:  # the panels draw the chosen robot's
                listener(self.show, self.session)

    def restage(self, arena: str | None = None, start: int | None = None) -> None:
        """Start the show again, in another arena or from another start pose if given.

        With neither, it restarts from its start pose; with values equal to the show's own,
        nothing changes (the Show tab's dropdowns echo every new show).
        """
        if self.show is None:
            return
        show = self.show
        new = dataclasses.replace(
            show,
            arena=arena if arena is not None else show.arena,
            start=start if start is not None else show.start,
        )
        if new != show or (arena is None and start is None):
            self.present(new)

    def advance(self, seconds: float) -> int:
        """Step the robots on show for `seconds` of wall time at `speed`; return the steps taken.

        After a life of T steps (and if `new_lives`), the same individual starts a new life
        from the next start pose, as in training.
        """
        session, show = self.session, self.show
        if session is None or show is None or not self.playing:
            return 0
        self._owed += seconds * self.speed
        steps = min(int(self._owed), MAX_STEPS_PER_ADVANCE)
        self._owed = min(self._owed - steps, 1.0)
        if steps:
            session.step(steps)
            if self.new_lives and show.life and session.robots[0].t >= show.life:
                self.present(dataclasses.replace(show, start=(show.start + 1) % sim.N_START_POSES))
        return steps

    def set_noise(self, sigma: float) -> None:
        """Sensor noise σ, now and for every later show.

        Raises:
            LiveError: σ out of the settings' range (`app.phases.live.checked_noise`), nothing kept.
        """
        sigma = checked_noise(sigma)
        if self.session is not None:
            self.session.set_noise(sigma)
        self.noise_sigma = sigma

    def set_learning(self, learning: LearningSettings) -> None:
        """Online learning settings, now and for every later show."""
        self.learning = learning
        if self.session is not None:
            self.session.set_learning(learning)

    def break_sensors(self, sensors: Sequence[int], mode: str) -> None:
        """Break sensors of every robot on show now; new lives stop, so the recovery is seen."""
        if self.session is None:
            raise DashboardInputError("nothing on show to break")
        self.session.break_sensors(sensors, mode)
        self.new_lives = False

    def repair(self) -> None:
        if self.session is not None:
            self.session.repair()
