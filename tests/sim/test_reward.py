"""Eq. 2.7 reward terms, by hand."""

import numpy as np
import pytest

import sim


def readings(*values: float) -> np.ndarray:
    row = np.zeros(8)
    row[: len(values)] = values
    return row


def terms_of(true: np.ndarray, left: float, right: float) -> dict[str, float]:
    terms = sim.reward_terms(true[None], np.array([[left, right]]))
    assert set(terms) == {"reward", "reward/speed", "reward/straightness", "reward/near_wall"}
    return {k: float(v[0]) for k, v in terms.items()}


@pytest.mark.parametrize(
    ("true", "left", "right", "speed", "straightness", "near_wall"),
    [
        (readings(500), 10, 10, 1.0, 1.0, 1.0),  # full speed ahead along a wall
        (readings(500), 5, 10, 0.75, 0.5, 1.0),  # |10 - 5| / 20 = 1/4, sqrt = 1/2
        (readings(500), 10, 5, 0.75, 0.5, 1.0),  # turning either way costs the same
        (readings(0, 300), -10, -10, -1.0, 1.0, 1.0),  # reversing is punished
        (readings(500), -10, 10, 0.0, 0.0, 1.0),  # turning in place earns nothing
        (readings(500), 2, 7, 0.45, 0.5, 1.0),
        (readings(999.99, 50), 10, 10, 1.0, 1.0, 1.0),  # close, but not touching
        (readings(1000.0, 50), 10, 10, 1.0, 1.0, 0.0),  # C = 0 at exactly 1000: touching
        (readings(1023.0), 10, 10, 1.0, 1.0, 0.0),
        (readings(100.0, 100.0), 10, 10, 1.0, 1.0, 0.0),  # all ≤ 100: no wall near
        (readings(100.001), 10, 10, 1.0, 1.0, 1.0),
        (readings(), 10, 10, 1.0, 1.0, 0.0),
        (readings(500), 25, 30, 1.0, 1.0, 1.0),  # commands are clipped to -10..10 first
    ],
)
def test_reward_terms_by_hand(
    true: np.ndarray,
    left: float,
    right: float,
    speed: float,
    straightness: float,
    near_wall: float,
) -> None:
    terms = terms_of(true, left, right)
    assert terms["reward/speed"] == pytest.approx(speed, abs=1e-12)
    assert terms["reward/straightness"] == pytest.approx(straightness, abs=1e-12)
    assert terms["reward/near_wall"] == near_wall
    assert terms["reward"] == pytest.approx(speed * straightness * near_wall, abs=1e-12)


def test_reward_is_batched_and_checks_shapes() -> None:
    true = np.stack([readings(500), readings(), readings(1000)])
    commands = np.array([[10.0, 10.0], [10.0, 10.0], [10.0, 10.0]])
    np.testing.assert_array_equal(sim.reward_terms(true, commands)["reward"], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"commands must have shape \(3, 2\)"):
        sim.reward_terms(true, commands[:2])
    with pytest.raises(ValueError, match=r"readings must have shape \(N, 8\)"):
        sim.reward_terms(true[:, :4], commands)


def test_the_table_matches_the_formula_written_with_numpy() -> None:
    """The compiled table against Eq. 2.7 spelled out in numpy, bit for bit."""
    rng = np.random.default_rng(4)
    true = rng.choice([0.0, 50.0, 100.0, 100.5, 640.0, 999.9, 1000.0, 1023.0], (500, 8))
    commands = rng.uniform(-12, 12, (500, 2))
    commands[::7] = np.round(commands[::7])
    out = np.full((500, 4), np.nan)
    table = sim.reward_table(true, commands, out=out)
    assert table is out
    cmd = np.clip(commands, -10, 10)
    speed = (cmd[:, 1] + cmd[:, 0]) / 20
    straightness = 1 - np.sqrt(np.abs(cmd[:, 1] - cmd[:, 0]) / 20)
    near = (np.all(true < 1000, axis=1) & np.any(true > 100, axis=1)).astype(float)
    assert np.array_equal(
        table, np.stack([speed * straightness * near, speed, straightness, near], 1)
    )
    with pytest.raises(ValueError, match="out must be a float64 array of shape"):
        sim.reward_table(true, commands, out=np.zeros((500, 3)))
