"""Reading a scenario file that is hostile or merely unusual: size, nesting, BOM and line ends."""

import pathlib
import subprocess
import sys

import pytest

from cdus.scenario import config as cfg
from cdus.scenario.config import ConfigError, load_scenario, parse_scenario, parse_value
from tests.scenario.common import MINIMAL, base

ROOT = pathlib.Path(__file__).resolve().parents[2]
SHIPPED = sorted((ROOT / "configs").glob("*.toml"))


@pytest.mark.parametrize("config", SHIPPED, ids=lambda p: p.name)
@pytest.mark.parametrize("variant", ["bom", "crlf", "bom+crlf", "cr"])
def test_a_windows_copy_of_every_shipped_config_loads_as_the_original(tmp_path, config, variant):
    text = config.read_bytes()
    if "crlf" in variant:
        text = text.replace(b"\n", b"\r\n")
    if variant == "cr":
        text = text.replace(b"\n", b"\r")
    if "bom" in variant:
        text = b"\xef\xbb\xbf" + text
    copy = tmp_path / config.name
    copy.write_bytes(text)
    original = load_scenario(config)
    loaded = load_scenario(copy)
    assert loaded.raw == original.raw and loaded.vehicles == original.vehicles and loaded.edges == original.edges


@pytest.mark.parametrize("opening", ["[", "{a = "])
def test_deep_nesting_is_a_config_error_naming_the_file_not_a_recursion_error(tmp_path, opening):
    f = tmp_path / "deep.toml"
    close = "]" if opening == "[" else "}"
    f.write_text("x = " + opening * 50_000 + "1" + close * 50_000 + "\n")
    with pytest.raises(ConfigError) as e:
        load_scenario(f)
    assert str(f) in str(e.value) and "nested deeper than 32" in str(e.value)


def test_nesting_just_past_the_limit_is_refused_and_at_the_limit_reaches_validation(tmp_path):
    f = tmp_path / "n.toml"
    f.write_text("x = " + "[" * 33 + "1" + "]" * 33 + "\n")
    with pytest.raises(ConfigError, match="nested deeper"):
        load_scenario(f)
    f.write_text("x = " + "[" * 32 + "1" + "]" * 32 + "\n")
    with pytest.raises(ConfigError) as e:
        load_scenario(f)
    assert "nested deeper" not in str(e.value) and "x: unknown section" in str(e.value)


def test_brackets_inside_strings_and_comments_do_not_count_as_nesting(tmp_path):
    f = tmp_path / "s.toml"
    deep = "[" * 100
    f.write_text(MINIMAL.replace('name = "two_boats"', f'name = "two_boats"\ndescription = "{deep}" # {deep}\n'
                                 f"# {deep}\n"))
    assert load_scenario(f).description == deep


def test_deep_data_and_deep_overrides_are_config_errors():
    deep: list = []
    node = deep
    for _ in range(5000):
        node.append([])
        node = node[0]
    data = base()
    data["scenario"]["description"] = deep
    with pytest.raises(ConfigError, match="nested deeper"):
        parse_scenario(data)
    with pytest.raises(ConfigError, match="nested deeper"):
        parse_scenario(base(), overrides={"scenario.description": deep})
    assert parse_value("[" * 50_000) == "[" * 50_000  # kept as text, no RecursionError


def test_a_file_over_the_size_limit_is_refused_before_parsing(tmp_path, monkeypatch):
    f = tmp_path / "big.toml"
    f.write_text(MINIMAL + "#" * 200 + "\n")
    monkeypatch.setattr(cfg, "MAX_FILE_BYTES", len(MINIMAL) + 100)
    parsed = []
    monkeypatch.setattr(cfg.tomllib, "loads", lambda *a, **k: parsed.append(1))
    with pytest.raises(ConfigError) as e:
        load_scenario(f)
    assert "size limit" in str(e.value) and str(f) in str(e.value) and not parsed


def test_the_real_size_limit_is_4_mb_and_a_file_of_it_is_refused(tmp_path):
    assert cfg.MAX_FILE_BYTES == 4 * 1024 * 1024
    f = tmp_path / "big.toml"
    with open(f, "wb") as fh:
        fh.write(MINIMAL.encode())
        fh.write(b"#" * cfg.MAX_FILE_BYTES + b"\n")
    with pytest.raises(ConfigError, match="larger than 4 MB"):
        load_scenario(f)


def test_a_top_level_json_value_that_is_not_a_table_is_a_config_error(tmp_path):
    f = tmp_path / "s.json"
    f.write_text("[1, 2]")
    with pytest.raises(ConfigError, match="table of sections"):
        load_scenario(f)


@pytest.mark.parametrize("body", ["x = " + "[" * 50_000 + "\n"])
def test_cdus_sim_exits_2_on_deep_nesting_without_a_traceback(tmp_path, body):
    f = tmp_path / "deep.toml"
    f.write_text(body)
    r = subprocess.run([sys.executable, "-m", "cdus", "sim", str(f)], capture_output=True, text=True, timeout=120,
                       cwd=ROOT)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and str(f) in r.stderr and "nested deeper" in r.stderr


def test_a_fifo_nobody_writes_into_or_a_directory_given_as_the_config_is_refused(tmp_path, monkeypatch):
    """Issue 27: a FIFO given as the config hung `cdus sim` (open waited for a writer for ever).
    One nothing is written into is refused after PIPE_WAIT_S, naming what it is; the CLI exits 2
    (run in a child so a regression hangs only it, and is killed)."""
    import os

    from cdus.scenario import config

    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)
    res = subprocess.run([sys.executable, "-c", "import sys; import cdus.scenario.config as c; c.PIPE_WAIT_S = 0.2; "
                          "from cdus.app.cli import main; sys.exit(main(sys.argv[1:]))", "sim", str(fifo), "-q"],
                         capture_output=True, text=True, timeout=30)  # first: a hang is killed here, not below
    assert res.returncode == 2 and "named pipe (FIFO) nothing was written into" in res.stderr, res.stderr
    assert "nothing was started" in res.stderr
    monkeypatch.setattr(config, "PIPE_WAIT_S", 0.2)
    with pytest.raises(ConfigError, match=r"file: is a named pipe \(FIFO\) nothing was written into within 0.2 s"):
        load_scenario(fifo)
    with pytest.raises(ConfigError, match=r"file: is a directory, not a regular file"):
        load_scenario(tmp_path)


def test_a_pipe_with_a_writer_is_read_as_the_config():
    """`cdus sim <(...)` and `... | cdus sim /dev/stdin` read the config from a pipe; 0642f64
    refused every pipe ("is a named pipe (FIFO), not a regular file"), which worked before it."""
    import os

    text = (ROOT / "configs" / "lake_circle.toml").read_bytes()
    r, w = os.pipe()
    try:
        os.write(w, text)  # a few KiB: within the pipe's buffer
        os.close(w)
        sc = load_scenario(f"/dev/fd/{r}")
    finally:
        os.close(r)
    whole = load_scenario(ROOT / "configs" / "lake_circle.toml")
    assert (sc.name, sc.ids, sc.duration) == (whole.name, whole.ids, whole.duration)


@pytest.mark.parametrize("bad", ["../../escaped", "/tmp/abs", "a\\b", "runs/x"])
def test_a_scenario_name_with_a_path_separator_is_refused_where_it_enters(bad):
    """`cdus sim` names its run directory runs/<name>-<time>: a name of "../../escaped" made
    ../../escaped-<time>/ (seen, with its metrics.json) and "/x" an absolute path. Refused,
    naming the field, with a name that would do."""
    with pytest.raises(ConfigError, match=r"scenario\.name: must not contain / or \\ \(it names the run directory"):
        parse_scenario({**base(), "scenario": {"name": bad}})


def test_a_scenario_name_with_escape_sequences_is_refused_where_it_enters():
    """Issue 27: a scenario.name with escape sequences reached the terminal raw from `cdus sim`
    (its summary, its progress line, the run directory's name). It is printed and names files:
    refused where it enters, shown escaped; a printable Unicode name is fine."""
    for bad in ("lake\x1b[31mRED\x07", "two\nlines", "rtl\u202eeman"):
        with pytest.raises(ConfigError, match=r"scenario\.name: must be printable text on one line") as e:
            parse_scenario({**base(), "scenario": {"name": bad}})
        assert "\x1b" not in str(e.value) and "\n" not in str(e.value).split("scenario.name")[1]
    assert parse_scenario({**base(), "scenario": {"name": "lac_Léman-2"}}).name == "lac_Léman-2"
