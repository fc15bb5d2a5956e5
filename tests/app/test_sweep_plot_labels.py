"""sweep.png: every value in a legend or the title carries its unit, and a panel with no
values shows no scale."""

from matplotlib.figure import Figure

from cdus.app.stats import describe
from cdus.app.sweep import CellSummary, plot, value_label


def _cell(cell, settle, error):
    c = CellSummary(cell, runs=len(error), ok=len(error))
    c.values["coord_settle_s"] = settle
    c.values["final_coord_error_max"] = error
    c.stats = {f: describe(v, seed=0) for f, v in c.values.items()}
    return c


def drawn_figure(monkeypatch, *args):
    figs = []
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: figs.append(self))
    plot(*args)
    (fig,) = figs
    return fig


def test_values_carry_their_physical_units():
    assert value_label("link.delay.base", 0.2) == "link.delay.base=0.2 s"
    assert value_label("rates.control", 20) == "rates.control=20 Hz"
    assert value_label("link.loss", 0.2) == "link.loss=0.2"
    assert value_label("link.policy", "hold") == "link.policy=hold"


def test_legend_and_title_say_the_units(monkeypatch, tmp_path):
    keys = ["link.loss", "link.delay.base", "rates.control"]
    cells = [_cell((("link.loss", loss), ("link.delay.base", d), ("rates.control", 20)), [10.0, 12.0], [0.01, 0.02])
             for loss in (0, 0.2) for d in (0, 0.1)]
    fig = drawn_figure(monkeypatch, keys, cells, tmp_path / "p.png", "t")
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert legend == ["link.delay.base=0 s", "link.delay.base=0.1 s"]
    assert "rates.control=20 Hz" in fig.get_suptitle()


def test_a_panel_with_nothing_to_show_has_no_scale(monkeypatch, tmp_path):
    cells = [_cell((("link.loss", 0),), [], [0.1, 0.2]), _cell((("link.loss", 0.2),), [], [0.2, 0.3])]
    fig = drawn_figure(monkeypatch, ["link.loss"], cells, tmp_path / "p.png")
    settle, error = fig.axes
    assert list(settle.get_yticks()) == [] and len(error.get_yticks()) > 0


def test_the_x_axis_carries_its_unit_and_the_figure_says_what_the_error_bars_and_markers_are(monkeypatch, tmp_path):
    """Paper cuts of issue 18: no unit on the x axis; error bars not named; "never" only as
    missing points."""
    cells = [_cell((("link.delay.base", d),), settle, [0.01, 0.02]) for d, settle in ((0.0, [10.0, 12.0]),
                                                                                       (0.2, [11.0]))]
    fig = drawn_figure(monkeypatch, ["link.delay.base"], cells, tmp_path / "p.png")
    assert [ax.get_xlabel() for ax in fig.axes] == ["link.delay.base (s)"] * 2
    assert "error bars: 95 % bootstrap CI of the mean" in fig.get_suptitle()
    assert "▼: runs that never settled" in fig.axes[0].get_title()
    assert "1/2 never" in [t.get_text() for t in fig.axes[0].texts]


def test_never_labels_of_neighbouring_cells_do_not_overlap(tmp_path):
    """README's radio sweep (radio.tx_power = -8, -6, -4, -2, 0, 5, 20; the first five never
    settled): the five '2/2 never' labels were drawn on one row and ran into each other
    ('2/2 ne2/2 ne2/2 ...'). Each label is now moved down a row while it would overlap one
    already drawn."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    figs = []
    original = Figure.savefig

    def keep(self, *a, **k):
        figs.append(self)
        return original(self, *a, **k)

    cells = [_cell((("radio.tx_power", p),), [] if p <= 0 else [100.0, 110.0], [1.0, 2.0])
             for p in (-8, -6, -4, -2, 0, 5, 20)]
    import pytest
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Figure, "savefig", keep)
        drawn = plot(["radio.tx_power"], cells, tmp_path / "p.png")
    assert drawn["never"] == ["2/2 never"] * 5
    (fig,) = figs
    renderer = FigureCanvasAgg(fig).get_renderer()
    boxes = [t.get_window_extent(renderer) for t in fig.axes[0].texts if t.get_text().endswith("never")]
    assert len(boxes) == 5
    overlaps = [(i, j) for i in range(5) for j in range(i + 1, 5) if boxes[i].overlaps(boxes[j])]
    assert overlaps == []
