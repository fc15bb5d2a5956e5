"""sweep.png: keys in words (a label table, a fallback for the others), every value in a legend or
the title with its unit, a panel with no values shows no scale."""

from matplotlib.figure import Figure

from cdus.app.stats import describe
import pytest

from cdus.app.sweepcells import CellSummary, summarize
from cdus.app.sweepplot import axis_label, dodge_offsets, plain_number, plot, value_label
from tests.app.test_sweepcells import cell_of


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
    assert value_label("link.delay.base", 0.2) == "Link delay = 0.2 s"
    assert value_label("rates.control", 20) == "Control rate = 20 Hz"
    assert value_label("link.loss", 0.2) == "Loss probability = 0.2"
    assert value_label("link.policy", "hold") == "Stale-neighbour policy = hold"
    assert value_label("vehicle.usv1.delay.base", 0.1) == "Vehicle usv1 delay base = 0.1 s"


def test_legend_and_title_say_the_units(monkeypatch, tmp_path):
    keys = ["link.loss", "link.delay.base", "rates.control"]
    cells = [_cell((("link.loss", loss), ("link.delay.base", d), ("rates.control", 20)), [10.0, 12.0], [0.01, 0.02])
             for loss in (0, 0.2) for d in (0, 0.1)]
    fig = drawn_figure(monkeypatch, keys, cells, tmp_path / "p.png", "t")
    (legend,) = fig.legends  # one for both panels, under them
    assert [t.get_text() for t in legend.get_texts()] == ["Link delay = 0 s", "Link delay = 0.1 s"]
    assert "Control rate = 20 Hz" in fig.get_suptitle()
    assert [ax.get_xlabel() for ax in fig.axes] == ["Loss probability"] * 2


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
    assert [ax.get_xlabel() for ax in fig.axes] == ["Link delay (s)"] * 2
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


def _errorbar_xs(ax) -> list[list[float]]:
    """The x of each series' points (the errorbar lines with markers), in drawing order."""
    return [list(line.get_xdata()) for line in ax.lines if line.get_marker() == "o"]


def test_series_at_one_x_are_moved_apart_symmetrically(monkeypatch, tmp_path):
    """Issue 27: points and error bars of different series at one x were drawn on top of each other."""
    cells = [_cell((("link.delay.base", d), ("link.policy", p)), [10.0, 12.0], [0.01, 0.02])
             for d in (0.0, 0.1, 0.2) for p in ("hold", "timeout", "extrapolate")]
    fig = drawn_figure(monkeypatch, ["link.delay.base", "link.policy"], cells, tmp_path / "p.png")
    for ax in fig.axes:
        xs = _errorbar_xs(ax)
        assert len(xs) == 3
        for j, x in enumerate((0.0, 0.1, 0.2)):
            at = [series[j] for series in xs]
            assert at == pytest.approx([x - 0.01, x, x + 0.01])  # DODGE_STEP of the 0.1 spacing apart
    assert "series moved apart in x" in fig.get_suptitle()


def test_dodge_offsets():
    assert dodge_offsets(1, [0.0, 0.1]) == [0.0]
    assert dodge_offsets(2, [0.0, 0.1, 0.2]) == pytest.approx([-0.005, 0.005])
    assert dodge_offsets(2, [0, 1, 2]) == pytest.approx([-0.05, 0.05])  # categories: one apart
    many = dodge_offsets(9, [0.0, 1.0])  # closer, all within DODGE_SPREAD of the spacing
    assert many[-1] - many[0] == pytest.approx(0.4) and many == sorted(many) and sum(many) == pytest.approx(0)
    assert dodge_offsets(2, [5.0]) == pytest.approx([-0.25, 0.25])  # one x only: a tenth of its size
    assert dodge_offsets(2, [0.0]) == pytest.approx([-0.05, 0.05])


def test_a_categorical_axis_keeps_its_ticks_on_the_categories(monkeypatch, tmp_path):
    cells = [_cell((("link.policy", p), ("rates.control", r)), [10.0], [0.01]) for p in ("hold", "extrapolate")
             for r in (20, 50)]
    fig = drawn_figure(monkeypatch, ["link.policy", "rates.control"], cells, tmp_path / "p.png")
    ax = fig.axes[0]
    assert list(ax.get_xticks()) == [0, 1] and [t.get_text() for t in ax.get_xticklabels()] == ["hold", "extrapolate"]
    assert [xs for xs in _errorbar_xs(ax)] == [pytest.approx([-0.05, 0.95]), pytest.approx([0.05, 1.05])]


def _log_labels(fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig).draw()
    axis = fig.axes[1].yaxis
    lo, hi = fig.axes[1].get_ylim()
    major = [t.get_text() for t in axis.get_ticklabels() if lo <= t.get_position()[1] <= hi]
    minor = [t.get_text() for t in axis.get_ticklabels(minor=True) if t.get_text()]
    return major, minor


def test_the_log_axis_is_labelled_with_plain_numbers_only_at_major_ticks(monkeypatch, tmp_path):
    """Issue 27: the error panel's log axis labelled its minor ticks 6×10⁻², 4×10⁻², 3×10⁻²..."""
    cells = [_cell((("link.loss", x),), [10.0], [e, e * 1.2]) for x, e in ((0, 0.015), (0.2, 0.04), (0.4, 0.15))]
    major, minor = _log_labels(drawn_figure(monkeypatch, ["link.loss"], cells, tmp_path / "p.png"))
    assert minor == []
    assert {"0.02", "0.05", "0.1"} <= set(major) <= {"0.01", "0.02", "0.05", "0.1", "0.2"}  # 1, 2, 5 x decades
    wide = [_cell((("link.loss", x),), [10.0], [e]) for x, e in ((0, 1e-6), (0.2, 1e-3), (0.4, 2.0))]
    major, minor = _log_labels(drawn_figure(monkeypatch, ["link.loss"], wide, tmp_path / "q.png"))
    assert minor == [] and "0.001" in major and "1" in major
    assert all(m in ("0.001", "0.01", "0.1", "1", "10") or m.startswith("$10^{") for m in major), major


def test_a_log_axis_within_a_decade_says_each_tick_s_own_value(monkeypatch, tmp_path):
    """Seen in a README-style sweep (lake_circle, 20% loss, 40 s): final errors 0.22-0.60 rad,
    where only 0.5 of 1, 2 and 5 times the decades falls, so matplotlib ticks every 0.05 and the
    labels read 0.2, 0.2, 0.3, 0.4, 0.4, 0.5, 0.5, 0.6, 0.6, 0.7: 0.25 said 0.2, 0.35 said 0.4."""
    cells = [_cell((("link.delay.base", x),), [10.0], [0.22, 0.6]) for x in (0, 0.1, 0.2)]
    fig = drawn_figure(monkeypatch, ["link.delay.base"], cells, tmp_path / "p.png")
    major, _ = _log_labels(fig)
    axis, (lo, hi) = fig.axes[1].yaxis, fig.axes[1].get_ylim()
    ticks = [t.get_position()[1] for t in axis.get_ticklabels() if lo <= t.get_position()[1] <= hi]
    assert len(major) >= 2 and len(set(major)) == len(major), major
    assert [float(m) for m in major] == pytest.approx(ticks), (major, ticks)


def test_plain_numbers():
    assert [plain_number(y) for y in (0.02, 0.5, 1.0, 5.0, 100.0, 1e-3)] == ["0.02", "0.5", "1", "5", "100", "0.001"]
    assert plain_number(1e-5) == "$10^{-5}$" and plain_number(2e-5) == r"$2\times10^{-5}$"
    assert plain_number(1e6) == "$10^{6}$" and plain_number(0.0) == ""
    assert [plain_number(y) for y in (0.25, 0.35, 0.1 + 0.2, 2.5e-5)] == ["0.25", "0.35", "0.3", r"$2.5\times10^{-5}$"]


@pytest.mark.parametrize("fmt, magic", [("pdf", b"%PDF-"), ("svg", b"<svg")])
def test_the_plot_is_written_as_a_vector_file_the_same_each_time(tmp_path, fmt, magic):
    cells = [_cell((("link.loss", x), ("link.policy", p)), [10.0, 11.0], [0.01, 0.02]) for x in (0, 0.2)
             for p in ("hold", "extrapolate")]
    for name in ("a", "b"):
        plot(["link.loss", "link.policy"], cells, tmp_path / f"{name}.{fmt}", "t")
    data = (tmp_path / f"a.{fmt}").read_bytes()
    assert magic in data[:400]
    assert data == (tmp_path / f"b.{fmt}").read_bytes()  # no creation date: the same rows, the same file


def test_axis_labels_are_words_with_units_where_known():
    assert axis_label("link.loss") == "Loss probability"
    assert axis_label("link.delay.base") == "Link delay (s)"
    assert axis_label("rates.control") == "Control rate (Hz)"
    assert axis_label("graph.topology") == "Graph topology"
    # a key the table does not know: its own parts in words, the unit from its last part
    assert axis_label("link.rule.0.loss") == "Link rule 0 loss (fraction)"
    assert axis_label("vehicle.usv1.gains.k") == "Vehicle usv1 gains k"
    assert axis_label("rates.sensor_x") == "Rates sensor x (Hz)"


def test_the_plot_marks_runs_that_never_settled_and_says_when_no_run_settled(tmp_path):
    cells = [cell_of(0.0, 3, [10.0, 12.0, 11.0], [0.01, 0.02, 0.015]), cell_of(0.1, 3, [20.0], [0.05, 0.06, 0.07])]
    drawn = plot(["link.delay.base"], cells, tmp_path / "a.png")
    assert drawn == {"empty": [], "never": ["2/3 never"], "offsets": {None: 0.0}}
    nothing = [cell_of(0.1, 2, [], [0.1, 0.2]), cell_of(0.2, 2, [], [0.2, 0.3])]
    drawn = plot(["link.delay.base"], nothing, tmp_path / "b.png")
    assert drawn["empty"] == ["no run settled"] and drawn["never"] == ["2/2 never", "2/2 never"]
    assert (tmp_path / "b.png").stat().st_size > 10_000
    assert "| 0.1 | 2/2 | 0/2 | never |" in summarize(["link.delay.base"], nothing)


def test_a_grid_of_words_and_tables_plots_as_categories(tmp_path):
    cells = []
    for policy in ("hold", "extrapolate"):
        c = CellSummary((("link.policy", policy), ("link.burst", {"p": 0.01, "r": 0.5})), runs=2, ok=2)
        c.values["coord_settle_s"] = [10.0, 11.0]
        c.values["final_coord_error_max"] = [0.01, 0.02]
        c.finish(seed=0)
        cells.append(c)
    drawn = plot(["link.policy", "link.burst"], cells, tmp_path / "c.png", "t")
    assert drawn == {"empty": [], "never": [], "offsets": {None: 0.0}}
    assert (tmp_path / "c.png").stat().st_size > 10_000
