"""What the README and the docs tell a reader to type exists: the README's command-line block
starts by activating the environment `make demo` makes, every `contactvisco` line in it parses
with the program's own parser (subcommand, options, `--set` keys of a real scene), its MPI line
runs as root on 2 cores, the `make` targets it names are in the Makefile, and every scene key
the README and docs/*.md name as `table.key` is a key of that table."""
import re
import shlex

import pytest

from helpers import ROOT

README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]


def command_block() -> list[str]:
    """The lines of the README's command-line block (comments dropped)."""
    text = README.read_text().split("## The command line", 1)[1]
    block = text.split("```sh\n", 1)[1].split("```", 1)[0]
    return [line.split("  #")[0].strip() for line in block.splitlines() if line.strip()]


def shell_blocks(text: str) -> list[str]:
    """The command lines of every ```sh block of a Markdown text (comments dropped)."""
    lines = []
    for block in re.findall(r"^```sh\n(.*?)^```", text, re.S | re.M):
        lines += [line.split("#")[0].strip() for line in block.splitlines()]
    return [line for line in lines if line]


def test_the_command_block_activates_the_environment_make_demo_makes():
    """A new shell has no `contactvisco` on its PATH: the block's first line activates the
    Makefile's Debian environment, and no later line needs another."""
    lines = command_block()
    makefile = (ROOT / "Makefile").read_text()
    venv = re.search(r"^else ifeq \(\$\(STACK\),debian\)\nVENV := (\S+)", makefile, re.M)
    assert venv, "the Makefile's Debian VENV"
    assert lines[0] == f"source {venv.group(1)}/bin/activate"
    assert all(line.split()[0] in ("contactvisco", "mpirun") for line in lines[1:]), lines


def test_every_contactvisco_line_parses_with_the_program_s_parser():
    """Each line's arguments are accepted by the command line's parser: a known subcommand,
    known options, PETSc options only where they go to PETSc, and --set keys that a built-in
    scene accepts (loaded, not solved)."""
    from contactvisco import cli, load_scene
    checked = 0
    for line in command_block()[1:]:
        words = shlex.split(line.split(">")[0])
        words = words[words.index("contactvisco") + 1:]
        args, petsc = cli._parser().parse_known_args(words)
        assert not [a for a in petsc if a.startswith("--")], line
        assert not petsc or args.command in ("run", "check"), line
        if getattr(args, "set", None) and args.scene == "paper":
            load_scene("paper", sets=args.set)
        checked += 1
    assert checked >= 8


def test_the_mpi_line_runs_as_root_on_two_cores():
    """Open MPI refuses root without --allow-run-as-root (the Makefile sets its variables
    instead), and more ranks than cores without --oversubscribe: the line asks for at most 2."""
    line = next(line for line in command_block() if line.startswith("mpirun"))
    words = shlex.split(line)
    assert "--allow-run-as-root" in words
    ranks = int(words[words.index("-n") + 1])
    assert 1 < ranks <= 2
    assert words[words.index("-n") + 2] == "contactvisco"


def test_the_make_targets_the_readme_names_exist():
    makefile = (ROOT / "Makefile").read_text()
    targets = set(re.findall(r"^([a-z][\w-]*):", makefile, re.M))
    named = [line.split()[-1] for line in shell_blocks(README.read_text())
             if line.startswith("make ")]
    assert named and set(named) <= targets, set(named) - targets


_KEY = re.compile(r"`([a-z_]+)\.([A-Za-z_]+)(?:[.\[=][^`]*)?`")
#: File names that look like keys: `memory.py`, `obstacle.png`.
SUFFIXES = {"py", "png", "pdf", "svg", "md", "csv", "json", "jsonl", "toml", "xdmf", "h5",
            "npz", "ipynb", "txt"}
#: Names in the code whose first part is a table's name: `solver.newton`,
#: `output.gather_mesh` (the package's modules, not scene keys).
CODE = {"solver": "contactvisco.solver", "output": "contactvisco.io.output"}
#: Wrong keys shown on purpose, with the error the program gives for them.
REFUSED = {("contact", "stifness"), ("time", "stpes"), ("dirichlet", "first")}


def is_code(table: str, key: str) -> bool:
    """`table.key` names a module or an attribute of the package's module of that name, or
    a constant (`solver.AUTO_ITERATIVE`; the keys in capitals are single letters: E, T)."""
    import importlib
    import pkgutil
    if len(key) > 1 and key.isupper():
        return True
    if table not in CODE:
        return False
    module = importlib.import_module(CODE[table])
    submodules = {m.name for m in pkgutil.iter_modules(getattr(module, "__path__", []))}
    return hasattr(module, key) or key in submodules


def named_keys(text: str) -> list[tuple[str, str]]:
    """The (table, key) of every code span `table.key`, `table.key = value` or
    `table.key.sub` of a Markdown text whose table is a scene table, file names and names
    in the code left out."""
    from contactvisco.scene.tables import TABLE_LISTS, TABLES
    return [(table, key) for table, key in _KEY.findall(text)
            if (table in TABLES or table in TABLE_LISTS) and key not in SUFFIXES
            and not is_code(table, key)]


def keys_of(table: str):
    from contactvisco.scene.tables import TABLE_LISTS, TABLES
    return (TABLES.get(table) or TABLE_LISTS[table]).KEYS


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_scene_key_the_docs_name_exists(page):
    """`contact.mu`, `output.fields`, `material.law`: a key the text names in a code span is
    a key of its table (a renamed key left in the docs fails here)."""
    unknown = {f"{table}.{key}" for table, key in named_keys(page.read_text())
               if key not in keys_of(table) and (table, key) not in REFUSED}
    assert not unknown, f"{page.name} names keys that do not exist: {sorted(unknown)}"


def test_the_wrong_keys_shown_on_purpose_are_wrong():
    """The misspellings the docs show with their error messages are no keys (else they
    would show nothing)."""
    assert all(key not in keys_of(table) for table, key in REFUSED)


def test_the_key_pattern_finds_keys():
    """The check above reads what it should: the README names several scene keys."""
    found = named_keys(README.read_text())
    assert ("contact", "p_nu") in found and ("material", "law") in found


def test_the_output_folder_table_names_the_files_a_run_writes():
    """docs/running.md's table of the output folder: each file name in its first column is
    one the program writes and owns (io.lock: what --overwrite removes, the lock file
    included), and each file the program owns that a reader opens is in the table."""
    from contactvisco.io import lock
    text = (ROOT / "docs" / "running.md").read_text()
    table = text.split("The output folder holds", 1)[1].split("\n\n", 2)[1]
    named = set()
    for line in table.splitlines()[2:]:
        first = line.split("|")[1]
        named |= {name.split("/")[0] + ("/" if "/" in name else "")
                  for name in re.findall(r"`([^`]+)`", first)}
    own = set(lock.OWN_FILES) | {lock.LOCK} | {f"{name}/" for name in lock.OWN_FOLDERS}
    assert named - {".h5"} <= own, sorted(named - own)
    readable = {name for name in own if not name.endswith(".tmp")
                and not name.endswith(".tmp.npz") and name != "solution.h5"}
    assert readable <= named, sorted(readable - named)
