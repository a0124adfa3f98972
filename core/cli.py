"""The ``hapticdesk`` command line.

Each sub-command lives in ``hapticdesk.commands.<name>`` with ``configure(parser)`` and
``run(args) -> int``; modules are imported only when their command runs, so ``hapticdesk
contacts`` never imports paho, python-can or matplotlib, and ``hapticdesk --help`` imports
neither numpy nor scipy (it lists the core's commands from the table below and the plugins'
from their light hook modules, issue 15 item 7: 0.14 CPU s against 1.39 before).
Plugins add commands of the same shape through ``register_commands`` (``demo`` comes from
the MQTT plugin); the registry is built only for those, and for the help that lists every
command.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import functools
import gc
import importlib
import importlib.util
import io
import logging
import os
import sys
import threading
import warnings
from collections.abc import Iterator
from typing import Any

# The BLAS libraries numpy and scipy load start a thread per core at import; on the estimator's
# small matrix products those threads only spin (a replay took 3.0–3.8 s of CPU instead of
# 1.9 s), so every command runs on one unless the user's environment says otherwise. Read by
# the libraries when they load, so set before any command module imports numpy.
BLAS_THREAD_VARIABLES = (
    "OPENBLAS_NUM_THREADS",
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
)

# name -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "init": ("hapticdesk.commands.init", "start a layout for a desk"),
    "contacts": ("hapticdesk.commands.contacts", "estimate contacts from a recording"),
    "simulate": ("hapticdesk.commands.simulate", "simulate a scene on a desk into a recording"),
    "bench": ("hapticdesk.commands.bench", "error against run time for every method"),
    "thresholds": ("hapticdesk.commands.thresholds", "derive F_tth and F_rth from presses"),
    "characterize": ("hapticdesk.commands.characterize", "measure a desk's noise, modes, drift"),
    "calibrate": ("hapticdesk.commands.calibrate", "fit load cells' gains and places to a weight"),
    "plot": ("hapticdesk.commands.plot", "plot a recording and its contacts"),
    "check": ("hapticdesk.commands.check", "validate and explain a layout"),
    "strokes": ("hapticdesk.commands.strokes", "classify or record stroke templates"),
    "run": ("hapticdesk.commands.run", "sense, recognise gestures and dispatch actions"),
    "plugins": ("hapticdesk.commands.plugins", "list installed plugins"),
    "record": ("hapticdesk.commands.record", "record a source to a recording or CAN log"),
    "emulate": ("hapticdesk.commands.emulate", "send a simulated desk's frames onto a CAN bus"),
}


def _available(with_plugins: bool = True) -> dict[str, tuple[Any, str]]:
    """Command name -> (module or its dotted name, one-line help): the core's, then plugins'."""
    out: dict[str, tuple[Any, str]] = {}
    for name, (module, text) in COMMANDS.items():
        if importlib.util.find_spec(module) is not None:
            out[name] = (module, text)
    if with_plugins:
        out.update(_plugin_commands())
    return out


@functools.cache
def _plugin_commands() -> dict[str, tuple[Any, str]]:
    from hapticdesk.errors import ConfigError
    from hapticdesk.plugin_loading import load_registry

    try:
        registry = load_registry()
    except ConfigError as err:  # e.g. two plugins registering one name
        logging.getLogger(__name__).warning("plugins: %s", err)
        return {}
    out: dict[str, tuple[Any, str]] = {}
    for name, command in registry.commands.items():
        if name in COMMANDS:
            logging.getLogger(__name__).warning(
                "plugin `%s` registers command `%s`, which hapticdesk has already; skipped",
                command.plugin,
                name,
            )
            continue
        out[name] = (command.factory, command.description)
    return out


def _module(ref: Any) -> Any:
    return importlib.import_module(ref) if isinstance(ref, str) else ref


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hapticdesk",
        description="A desk on force/torque sensors as a touch and gesture surface.",
    )
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    parser.add_argument(
        "--debug",
        action="store_true",
        help=f"show the traceback of an unexpected error (or set {DEBUG_VARIABLE}=1)",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    # a core command needs no plugin loaded; anything else (or the help) may be a plugin's
    for name, (module, text) in _available(with_plugins=only not in COMMANDS).items():
        p = sub.add_parser(name, help=text, description=text)
        # Only the command that runs is configured: the list of commands needs no import.
        if only == name:
            _module(module).configure(p)
    return parser


#: set to 1 (or give --debug) to see an unexpected error's traceback instead of one line
DEBUG_VARIABLE = "HAPTICDESK_DEBUG"
#: what in it means off (anything else: on)
OFF_WORDS = frozenset({"", "0", "false", "no", "off"})

#: the packages that bring a BLAS of their own. numpy's loads with numpy itself; scipy's with
#: whichever of its compiled modules first links it (scipy.linalg's, most often), so every
#: module of scipy loads with the variables set
BLAS_PACKAGES = ("numpy", "scipy")


def _loads_a_blas(name: str) -> bool:
    return name in BLAS_PACKAGES or name.startswith("scipy.")


class _OneBlasThread:
    """Loads numpy and scipy, when something first imports them, with one BLAS thread
    unless the user's environment says otherwise; nothing before. (Importing both at start
    cost every command scipy.linalg, 0.15–0.7 s, whether it used scipy or not; so did loading
    scipy.linalg whenever scipy was imported, as numba does to check its version: 0.15 s of
    CPU of each estimating command.)

    The variables are read when the library loads, so they are set just for that moment and
    taken back: programs an ``exec`` action starts must not inherit them."""

    def find_spec(self, name: str, path: Any, target: Any = None) -> Any:
        if not _loads_a_blas(name):
            return None
        for finder in sys.meta_path:  # the finder that would have found it
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(name, path, target)
            if spec is not None:
                if spec.loader is not None:  # (a Loader by its methods)
                    wrapped: Any = _LoadingWithOneThread(spec.loader)
                    spec.loader = wrapped
                return spec
        return None


@contextlib.contextmanager
def _one_blas_thread() -> Iterator[None]:
    """The BLAS thread variables the environment does not set, set to 1 for the moment."""
    added = [name for name in BLAS_THREAD_VARIABLES if name not in os.environ]
    for name in added:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)


class _LoadingWithOneThread:
    """A module's own loader, run with the BLAS thread variables set (see above): a compiled
    module's library is loaded as the module is created, a package's modules as it runs."""

    def __init__(self, loader: Any) -> None:
        self.loader = loader

    def create_module(self, spec: Any) -> Any:
        with _one_blas_thread():
            return self.loader.create_module(spec)

    def exec_module(self, module: Any) -> None:
        module.__spec__.loader = module.__loader__ = self.loader  # (resources, reloads)
        with _one_blas_thread():
            self.loader.exec_module(module)


def load_blas_with_one_thread() -> None:
    """From now on numpy and scipy load with one BLAS thread each, when first imported
    (:class:`_OneBlasThread`; once per process)."""
    if not any(isinstance(finder, _OneBlasThread) for finder in sys.meta_path):
        sys.meta_path.insert(0, _OneBlasThread())


def entry() -> int:
    """``hapticdesk``, the program (its console script and ``python -m hapticdesk``):
    :func:`main` in a process of its own, which ends when it returns.

    Python's cyclic garbage collector walks every object the process holds each time it runs
    a full collection, and its exit runs several, over the modules' objects (numpy's,
    numba's: some 60,000 of them after ``contacts`` has loaded its kernels). Those objects
    live as long as the process; walking them finds nothing to free. So while a command's
    modules load the collector waits, and what they made is then frozen (``gc.freeze``:
    left out of every later collection); and once the command has returned, everything is
    frozen, so the exit ends the process without walking it (Python's exit never promised
    to finalise objects in reference cycles; files the commands write are closed by then,
    and standard output is flushed as before). Together about 0.1 s of CPU of
    ``hapticdesk contacts`` on a minute of data, 0.57 → 0.46 s (docs/performance.md). :func:`main`
    itself, called within another program (the tests), leaves the collector as it was."""
    code = main(own_process=True)
    gc.freeze()
    return code


def main(argv: list[str] | None = None, *, own_process: bool = False) -> int:
    """Runs the command ``argv`` names (default: the program's arguments); its exit code.
    ``own_process``: the process ends when this returns (:func:`entry`)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    command = next((a for a in argv if not a.startswith("-")), None)
    # known before the arguments are parsed (building the parser can fail too), and taken
    # wherever it is given: before or after the command's own arguments, but not after
    # "--", where everything is an argument (a file may be called --debug)
    options_end = argv.index("--") if "--" in argv else len(argv)
    given = "--debug" in argv[:options_end]
    debug = given or os.environ.get(DEBUG_VARIABLE, "").strip().lower() not in OFF_WORDS
    argv = [a for i, a in enumerate(argv) if i >= options_end or a != "--debug"]
    if sys.stdout is None:  # started with standard output closed (`hapticdesk … >&-`)
        sys.stdout = _ClosedOutput()
    try:
        code = _main(argv, command, debug, own_process)
        sys.stdout.flush()  # a full disk shows here, not as Python's complaint at exit
        return code
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # the reader of our output went away (`hapticdesk check L | head -1`): stop quietly,
        # as a shell tool does, and keep Python's exit from flushing into the closed pipe
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, what a shell reports for a tool the pipe stopped
    except OSError as err:
        if not _output_failed(err):
            if debug:
                raise
            print(_unexpected(command, err), file=sys.stderr)
            return 1
        # `hapticdesk check L > /dev/full`: say so once, and drop what could not be written
        # so that Python's exit does not try (and complain) again. (A full disk under a file
        # a command writes without naming it would read the same: "its output", not stdout.)
        what = "the standard output" if isinstance(sys.stdout, _ClosedOutput) else "its output"
        print(
            f"hapticdesk{f' {command}' if command else ''}: error: cannot write {what}: "
            f"{err.strerror or err}",
            file=sys.stderr,
        )
        sys.stdout = _ClosedOutput()
        return 2
    except Exception as err:  # the last safety net: a bug, or a failure nobody foresaw
        if debug:
            raise
        print(_unexpected(command, err), file=sys.stderr)
        return 1


class _ClosedOutput(io.TextIOBase):
    """Standard output that cannot be written (closed at start, or failed): each write is
    an OSError, which :func:`main` reports as one line."""

    def write(self, text: str) -> int:
        raise OSError(errno.EBADF, "it is closed")


#: an output that cannot take what is written: a full disk or quota, a device's failure
_CANNOT_WRITE = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO}


def _output_failed(err: OSError) -> bool:
    """Whether ``err`` is the output failing (standard output closed, a full disk under
    ``> /dev/full``) rather than a bug: the commands name the files they write themselves,
    so an output error without a file name is standard output's."""
    return isinstance(sys.stdout, _ClosedOutput) or (
        err.errno in _CANNOT_WRITE and err.filename is None
    )


def _main(argv: list[str], command: str | None, debug: bool, own_process: bool) -> int:
    load_blas_with_one_thread()
    with _loading(own_process):
        parser = build_parser(only=command)  # (the command's module imported)
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="%(levelname)s %(name)s: %(message)s",
    )
    if not args.command:
        parser.print_help()
        return 2
    if args.command in COMMANDS:
        module = importlib.import_module(COMMANDS[args.command][0])
    else:
        module = _module(_plugin_commands()[args.command][0])
    # Imported here, not at the top: yaml is not needed to print the list of commands.
    from hapticdesk.errors import ConfigError

    try:
        with _short_reports(args.command, debug):
            return int(module.run(args) or 0)
    except ConfigError as err:
        print(f"hapticdesk {args.command}: error: {err}", file=sys.stderr)
        return 2


@contextlib.contextmanager
def _loading(own_process: bool) -> Iterator[None]:
    """While a command's modules load (its module and what that imports), in a process of
    its own (:func:`entry`): the cyclic collector waits, and what they made is frozen after
    (it lives as long as the process). Within another program: nothing changes."""
    if not own_process or not gc.isenabled():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        gc.enable()


def _unexpected(command: str | None, err: BaseException) -> str:
    """One line for an error nothing else handled: what it says, its kind, how to see more."""
    lines = str(err).strip().splitlines()
    what = lines[0] if lines else ""
    if len(what) > 300:
        what = what[:300] + " …"
    if not what:
        what = "out of memory" if isinstance(err, MemoryError) else "no message"
    name = f"hapticdesk {command}" if command else "hapticdesk"
    if isinstance(err, ModuleNotFoundError):  # an optional part not installed: say which extra
        from hapticdesk.extras import install_hint

        hint = install_hint(err.name)
        if hint is not None:
            return f"{name}: error: {hint}"
    return (
        f"{name}: error: {what} (an unexpected {type(err).__name__}; run with --debug or "
        f"{DEBUG_VARIABLE}=1 for the traceback)"
    )


@contextlib.contextmanager
def _short_reports(command: str, debug: bool) -> Iterator[None]:
    """While a command runs, a library's warning (numpy's ``overflow encountered``) is one
    line naming the command, not the library's file and line; an error that ends another
    thread is one line too. ``debug`` keeps Python's own reports."""
    if debug:
        yield
        return

    def show(message: Any, category: type[Warning], *args: Any, **kwargs: Any) -> None:
        print(f"hapticdesk {command}: warning: {message} ({category.__name__})", file=sys.stderr)

    def thread_failed(hook: threading.ExceptHookArgs) -> None:
        if hook.exc_type is SystemExit or hook.exc_value is None:
            return
        name = hook.thread.name if hook.thread is not None else "a thread"
        print(
            f"{_unexpected(command, hook.exc_value)} (in thread {name})",
            file=sys.stderr,
        )

    saved = warnings.showwarning, threading.excepthook
    warnings.showwarning = show
    threading.excepthook = thread_failed
    try:
        yield
    finally:
        warnings.showwarning, threading.excepthook = saved


if __name__ == "__main__":
    sys.exit(entry())
