"""bench/shape.py, the shape report of the README's "Development" section: it runs on this
checkout, and on a small tree it finds each thing it is there to find (a long file, a clock
comparison, a finite-number check defined again, a number tested by hand, a module that asks
no question), and --check says so by its exit status."""

from pathlib import Path

from bench import shape

FINITE = '''"""Which numbers are finite?"""
import math


def finite(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
'''


def tree(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def test_a_tree_that_meets_every_aim_passes_the_check(tmp_path, capsys):
    root = tree(tmp_path, {"cdus/wire/bounds.py": FINITE, "cdus/__init__.py": "",
                           "world_sim/world.py": '"""What does the world do?"""\nclock = pick(args.clock)\n',
                           "vehicle_agent/agent.py": '"""Where is my vehicle: its agent."""\n'})
    assert shape.main(["--root", str(root), "--check"]) == 0
    out = capsys.readouterr().out
    assert "defined: cdus/wire/bounds.py:6 finite()" in out and "1 definitions" in out
    assert "# Aims missed: none" in out


def test_each_missed_aim_is_found_and_named(tmp_path, capsys):
    long = '"""How long can a file be?"""\n' + "x = 1\n" * 700
    copy = ('"""What does the agent do?"""\nimport math\n\n\ndef _num(v):\n'
            '    if isinstance(v, bool) or not isinstance(v, (int, float)):\n        return None\n'
            '    return v if math.isfinite(v) else None\n\n\nrun = loop if clock != "realtime" else sleep\n')
    by_hand = ('"""Notes on the world."""\n\n\ndef late(at):\n'
               '    if self.clock == "lockstep":\n        pass\n'
               '    return isinstance(at, (int, float)) and not isinstance(at, bool)\n\n\n'
               'def stamp(m):\n    return isinstance(m.t, float) and math.isfinite(m.t)\n')
    root = tree(tmp_path, {"cdus/wire/bounds.py": FINITE, "cdus/long.py": long,
                           "vehicle_agent/agent.py": copy, "world_sim/world.py": by_hand})
    assert shape.main(["--root", str(root), "--check", "--top", "2"]) == 1
    out = capsys.readouterr().out
    assert "   701 cdus/long.py" in out and "1 over)" in out
    assert 'world_sim/world.py:5:    if self.clock == "lockstep":' in out
    assert "written again: vehicle_agent/agent.py:6 _num()" in out
    assert "a number, not a bool, tested by hand: world_sim/world.py:7 late()" in out
    assert "written again: world_sim/world.py:11 stamp()" in out
    assert "3 definitions" in out
    assert out.split("# Modules whose")[1].split("#")[0].split("\n")[1:-2] == ["world_sim/world.py"]
    assert 'vehicle_agent/agent.py:11:run = loop if clock != "realtime" else sleep' in out
    assert "(2 lines in 2 files;" in out and "- the clock's name is compared in 2 files" in out
    assert "# Aims missed: 4" in out  # the long file, the clock in two places, the finite check, the question
    assert shape.main(["--root", str(root), "--top", "2"]) == 0  # without --check: a report, never a failure


def test_the_report_runs_on_this_checkout_and_names_its_longest_file(capsys):
    root = Path(__file__).resolve().parent.parent
    assert shape.main(["--top", "1"]) == 0
    out = capsys.readouterr().out
    longest = max(shape.sources(root), key=lambda p: len(p.read_bytes().splitlines()))
    assert out.split("\n\n")[0].splitlines()[1].split() == [str(len(longest.read_bytes().splitlines())),
                                                           longest.relative_to(root).as_posix()]
    assert "# The finite-number check" in out and "# Aims missed:" in out


def test_a_docstring_that_asks_whose_opens_with_a_question():
    import ast
    # world_sim/clocks.py and world_sim/liveness.py open so; "whose" was missing from the words that ask
    assert shape.opens_with_a_question(ast.parse('"""Whose clock does the world keep: the grants or the wall clock?"""'))
    assert not shape.opens_with_a_question(ast.parse('"""The world process: what is it made of?"""'))
