"""The ``muble`` command.

``muble [run] [OVERRIDES…]`` runs one episode (the main job); ``muble plugins`` lists every registered plugin;
``muble generate``, ``muble eval`` and ``muble render`` are the dataset, evaluation and rendering jobs, and
``muble compare`` sets evaluation runs side by side. Every job is a Hydra application: overrides such as
``renderer=blender`` and multirun (``-m``) work the same for each.
"""
from __future__ import annotations

import importlib
import logging
import os
import sys

from muble.core.errors import MubleError

log = logging.getLogger(__name__)

# Command -> (module, description). Each module exposes ``main(argv: list[str]) -> int``.
COMMANDS: dict[str, tuple[str, str]] = {
    "run": ("muble.app.run", "run one episode (default command)"),
    "plugins": ("muble.app.plugins_cmd", "list registered plugins by kind with their providing package"),
    "render": ("muble.app.render", "render a scene file or an episode's keyframes to PNGs and a GIF"),
    "generate": ("muble.app.generate", "generate the SHOP-VRB2 dataset (sharded, resumable)"),
    "eval": ("muble.app.evaluate", "evaluate an agent over a dataset split"),
    "train": ("muble.app.train", "train a learned part (planner, instruction parser, attribute recogniser)"),
    "data": ("muble.app.data", "write a frozen protocol split's shipped scene and instruction files to a folder"),
    "verify": ("muble.app.verify", "replay an eval run's recorded decisions and compare the physics, episode by episode"),
    "compare": ("muble.app.compare", "compare `muble eval` runs: success with 95% intervals, paired McNemar tests"),
    "site": ("muble.app.site", "a static website of `muble eval` runs: leaderboard, runs, episodes"),
    "export": ("muble.app.export", "export a split's sequences as a LeRobot dataset (needs muble[lerobot])"),
    "serve": ("muble.app.serve", "serve episodes to an agent in another process (JSON protocol over ZeroMQ)"),
}

# Commands that are Hydra applications (the others parse their own arguments).
HYDRA_COMMANDS = ("run", "generate", "eval", "train")

USAGE = """usage: muble [COMMAND] [ARGS…]

commands:
{commands}

With no command, or when the first argument is a Hydra override (key=value) or flag (-m, --cfg …),
`run` is meant. `muble COMMAND --help` shows a command's own help (Hydra's for the jobs). `--verbose`
(anywhere) also shows third-party libraries' messages and MuBlE's debug log.
examples:
  muble renderer=mujoco seed=3
  muble -m task=measure_weight_single,stack_simple robot=Panda,UR5e
  muble plugins --kind renderer
"""


def usage() -> str:
    width = max(map(len, COMMANDS))
    lines = [f"  {name.ljust(width)}  {desc}" for name, (_, desc) in COMMANDS.items()]
    return USAGE.format(commands="\n".join(lines))


# The GL backends MuJoCo accepts on this platform (its own check raises deep inside the first import that renders).
_GL_BACKENDS = {"Linux": ("egl", "osmesa", "glx", "glfw"), "Darwin": ("cgl", "glfw"), "Windows": ("wgl", "glfw")}
_GL_SWITCHES = ("", "enable", "enabled", "on", "true", "1", "disable", "disabled", "off", "false", "0")


def check_gl_backend() -> str | None:
    """Why ``MUJOCO_GL`` cannot work here (an environment error, not a bug), or None."""
    import platform

    value = os.environ.get("MUJOCO_GL", "").lower().strip()
    valid = _GL_BACKENDS.get(platform.system(), ("glfw",))
    if value in _GL_SWITCHES or value in valid:
        return None
    return (f"environment: MUJOCO_GL={os.environ['MUJOCO_GL']!r:.60} is not a GL backend MuJoCo knows on "
            f"{platform.system()}; set MUJOCO_GL to one of {', '.join(valid)} (egl for headless rendering through "
            "Mesa) or unset it")


def main(argv: list[str] | None = None) -> int:
    from muble.quiet import quiet_third_party

    argv = list(sys.argv[1:] if argv is None else argv)
    verbose = "--verbose" in argv
    argv = [a for a in argv if a != "--verbose"]
    quiet_third_party(verbose)
    if argv and argv[0] in ("-h", "--help", "help"):
        print(usage())
        return 0
    if argv and argv[0] in COMMANDS:
        command, rest = argv[0], argv[1:]
    elif not argv or argv[0].startswith("-") or "=" in argv[0]:
        command, rest = "run", argv
    else:
        print(f"muble: unknown command '{argv[0]}'; valid commands: {', '.join(COMMANDS)}\n", file=sys.stderr)
        print(usage(), file=sys.stderr)
        return 2
    gl_problem = check_gl_backend()
    if gl_problem is not None:
        print(f"muble {command}: error: {gl_problem}", file=sys.stderr)
        return 2
    module_name, _ = COMMANDS[command]
    if verbose and command in HYDRA_COMMANDS:
        rest = [*rest, "hydra.verbose=[muble,muble_plugins]"]
    elif verbose:
        logging.basicConfig(level=logging.DEBUG, format="[%(name)s][%(levelname)s] - %(message)s")
    try:
        module = importlib.import_module(module_name)
        code = module.main(rest)
    except MubleError as e:
        print(f"muble {command}: error: {e}", file=sys.stderr)
        return 2
    return int(code or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
