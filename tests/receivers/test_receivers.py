"""The receiver registry: one spec per receiver, read by every stage (tsel_data/receivers)."""
import numpy as np
import pytest

from tsel_data import errors as rx_errors
from tsel_data import receivers as rx
from tsel_data.core.geometry import cart_to_sph
from support import REPO


def test_mic4_layout():
    side = 0.12
    m = rx.mic4_positions(side)
    r = side / np.sqrt(2)
    expected = r * np.array([[np.cos(np.radians(a)), np.sin(np.radians(a)), 0] for a in (45, 135, 225, 315)])
    np.testing.assert_allclose(m, expected, atol=1e-12)
    # neighbours are `side` apart; 0 front-left, 1 back-left, 2 back-right, 3 front-right
    assert np.linalg.norm(m[0] - m[1]) == pytest.approx(side)
    assert m[0][0] > 0 and m[0][1] > 0 and m[1][0] < 0 and m[1][1] > 0
    assert m[2][0] < 0 and m[2][1] < 0 and m[3][0] > 0 and m[3][1] < 0


def test_tetra_layout():
    t = rx.tetra_positions()
    az, el, r = cart_to_sph(t)
    np.testing.assert_allclose(r, 0.042)
    np.testing.assert_allclose(az, [45, -45, 135, -135], atol=1e-9)
    np.testing.assert_allclose(el, [35, -35, -35, 35], atol=1e-9)


@pytest.mark.parametrize("name", [n for n in rx.NAMES if not rx.RECEIVERS[n].configured
                                  and rx.RECEIVERS[n].model != "hrtf"])
def test_every_fixed_receiver_is_consistent(name):
    """Channel names, positions, preview, level and additive channels of a spec agree."""
    spec = rx.receiver(name)
    pose = rx.ArrayPose(name, (0.0, 0.0, 0.0), 0.0, 0.11 if spec.size_key else None)
    pos = pose.mics()
    c = len(pose.channel_names())
    assert pos.shape == (c, 3) and np.all(np.isfinite(pos))
    assert len(set(pose.channel_names())) == c
    pair = spec.stereo_pair(pos)
    if pair is None:
        assert spec.stereo_matrix().shape == (2, c)
    else:
        assert all(0 <= k < c for k in pair) and pair[0] != pair[1]
        assert pos[pair[0], 1] >= pos[pair[1], 1]  # left is the +y one
    assert all(0 <= k < c for k in spec.level_channels)
    assert spec.additive_gains(c).shape == (c,)
    assert spec.convention and spec.summary
    if not spec.coincident:  # spaced capsules are spaced
        d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)[np.triu_indices(c, 1)]
        assert d.min() > 1e-3
    assert pose.radius() >= np.linalg.norm(pos, axis=1).max() - 1e-12


def test_names_and_aliases_resolve_and_unknown_ones_are_one_clear_error():
    assert rx.receiver("mic") is rx.RECEIVERS["tetra"] and rx.canonical("MIC4") == "mic4"
    assert rx.canonical("nope") is None
    with pytest.raises(rx_errors.ConfigError, match=r"unknown receiver .*'nope'.*known: mic4, foa"):
        rx.receiver("nope")


def test_no_module_compares_receiver_names():
    """Every stage reads the spec: outside tsel_data/receivers no code compares a value with
    a receiver's name (``fmt == "foa"``, ``fmt in ("mic4", ...)``)."""
    import ast
    names = set(rx.NAMES) | set(rx.ALIASES)
    root = REPO
    found = []
    for path in [*root.glob("tsel_data/**/*.py"), *root.glob("tsel_baseline/**/*.py")]:
        if "receivers" in path.parts:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.Compare):
                continue
            consts = [n for n in ast.walk(node) if isinstance(n, ast.Constant) and n.value in names]
            if consts:
                found.append(f"{path.relative_to(root)}:{node.lineno}")
    assert not found, f"compare with the receiver's spec instead: {found}"


@pytest.mark.parametrize("overrides,message", [
    (['scene.format="custom"'], r"needs array.capsules"),
    (['scene.format="custom"', 'array.capsules=[[0.05, 0, 0], [0.05, 0, 0]]'], r"capsules\[0\] and \[1\] are 0 mm apart"),
    (['scene.format="custom"', 'array.capsules=[[0.05, 0, 0], [0, 0.05]]'], r"capsules\[1\] = \[0, 0.05\] is not \[x, y, z\]"),
    (['scene.format="custom"', 'array.capsules=[[50, 0, 0], [0, 0.05, 0]]'], r"more than 1 m .* metres"),
    (['scene.format="custom"', 'array.capsules=[[0.05, 0, 0], [0, 0.05, 0]]', 'array.patterns=["cardoid"]'],
     r"unknown pattern 'cardoid'"),
    (['scene.format="custom"', 'array.capsules=[[0.05, 0, 0], [0, 0.05, 0], [0, 0, 0.05]]',
      'array.patterns=["omni", "cardioid"]'], r"2 entries for 3 capsules"),
    (['scene.format="custom"', f'array.capsules={[[0.01 * k, 0, 0] for k in range(65)]}'], r"65 capsules; at most 64"),
    (['array.capsules=[[0.05, 0, 0], [0, 0.05, 0]]'], r"array.capsules is set but scene.format = 'mic4'"),
])
def test_bad_custom_arrays_are_one_clear_line(overrides, message):
    from tsel_data.config import load_config

    with pytest.raises(rx_errors.ConfigError, match=message):
        load_config(preset="demo", overrides=overrides)


def test_a_coincident_pair_of_directional_capsules_aimed_apart_is_an_array():
    """XY stereo: two cardioids at one point, 90° apart, is a receiver; the same omni twice is not."""
    from tsel_data.config import load_config
    from tsel_data.config.receiver import array_pose

    cfg = load_config(preset="demo", overrides=['scene.format="custom"', 'array.capsules=[[0, 0, 0], [0, 0, 0]]',
                                                'array.patterns=["cardioid"]', 'array.orientations=[[45, 0], [-45, 0]]'])
    pose = array_pose(cfg, (3.0, 3.0, 1.5), 0.0)
    assert pose.n_channels == 2 and pose.patterns == ("cardioid", "cardioid")
    assert pose.orientations == ((45.0, 0.0), (-45.0, 0.0))


def test_the_receivers_table_of_the_docs_is_the_registry():
    """docs/format.md's table is generated (python -m tsel_data.receivers.doc docs/format.md)."""

    from tsel_data.receivers.doc import render

    text = (REPO / "docs" / "format.md").read_text(encoding="utf-8")
    assert "<!-- receivers -->" in text and render(text) == text, \
        "docs/format.md is stale: run python -m tsel_data.receivers.doc docs/format.md"
