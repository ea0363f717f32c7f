"""What ``thermodrift run`` accepts: its config groups with their options, its top-level keys with their meaning.

Read from the registry, the shipped YAML files and the comments of ``conf/config.yaml``, without Hydra, MLflow
or torch, so that ``thermodrift run --help`` answers fast and a typo in an override is caught before Hydra
composes anything (Hydra would answer ``model=mrl`` with a stack of lines and ``n_trial=5`` with ``+n_trial``).
"""

from __future__ import annotations

import difflib
import importlib.resources
import re
import textwrap
from dataclasses import dataclass
from typing import Any

import yaml

from thermodrift.core import configs, registry
from thermodrift.core.cli import plain
from thermodrift.core.errors import InputError

# group -> (registry kind or None for YAML-only groups, what the group chooses)
GROUPS = {
    "dataset": ("dataset", "the recording: temperatures (°C) and displacements (µm)"),
    "split": (None, "which rows are held out for the evaluation"),
    "selector": ("selector", "which temperature sensors feed the model"),
    "model": ("model", "the thermal-error model, °C -> µm, tuned by Optuna"),
    "optimizer": ("optimizer", "the Optuna sampler that tunes the model"),
    "experiment": (None, "a preset that may override any key"),
    "automl": (None, "search across families instead of one model (thermodrift automl; automl.budget_fits=N)"),
}
# The keys under a group's node (`model.params.alpha=0.1`); experiment presets are global.
GROUP_KEYS = {"dataset": ["name", "params"], "split": ["kind", "params"], "selector": ["name", "params"],
              "model": ["name", "params", "search_space"], "optimizer": ["name", "params"],
              "automl": ["budget_fits", "timeout_s", "max_folds", "tpe_families", "top_rung", "ensemble_pool",
                         "ensemble_steps", "families", "n_jobs"]}
EXAMPLES = """\
  thermodrift run                                    demo_spindle, transfer_function tuned by tpe, 20 trials
  thermodrift run model=bp n_trials=50               another model, a larger budget
  thermodrift run model=bp model.params.trainer.epochs=100
  thermodrift run -m model=mlr,bp optimizer=tpe,pso  a grid: one job per combination
  thermodrift run dataset=recording_file dataset.params.table=my.csv dataset.params.manifest=my.yaml
  thermodrift run split=forward_chaining seed=1
  thermodrift run model=bp --cfg job                 print the composed config, run nothing
"""
_COMMENTED = re.compile(r"^(?P<indent> *)(?P<key>[A-Za-z_]\w*):(?P<value>.*?)(?:\s+#\s*(?P<doc>.*))?$")
_WIDTH = 110  # columns of the help text
_CONTINUED = re.compile(r"^ +#(?P<doc>.*)$")


@dataclass(frozen=True)
class Key:
    """A top-level config key (or a key of a section such as ``tracking``): its default and its meaning."""

    path: str
    default: str
    doc: str


def _config_text() -> str:
    return importlib.resources.files(configs.CONFIG_MODULE).joinpath("config.yaml").read_text(encoding="utf-8")


def keys() -> list[Key]:
    """The keys of ``conf/config.yaml`` (sections' keys as ``section.key``) with their comments (a comment
    continued on indented comment lines below it included); the Hydra block and the defaults list are left
    out."""
    out, section, last = [], None, None
    for line in _config_text().splitlines():
        m = _COMMENTED.match(line)
        more = _CONTINUED.match(line)
        if more and last is not None:  # the comment of the key above, continued
            out[-1] = last = Key(last.path, last.default, f"{last.doc} {more['doc'].strip()}".strip())
            continue
        last = None
        if not m:
            continue
        key, value, doc = m["key"], m["value"].strip(), (m["doc"] or "").strip()
        if not m["indent"]:
            section = key if not value else None
            if value and key not in ("defaults",):
                out.append(last := Key(key, value, doc))
        elif section and section != "hydra" and len(m["indent"]) == 2:
            out.append(last := Key(f"{section}.{key}", value, doc))
    return out


def defaults() -> dict[str, str]:
    """The default option of each group (the defaults list of ``conf/config.yaml``)."""
    listed = yaml.safe_load(_config_text()).get("defaults", [])
    return {k: v for item in listed if isinstance(item, dict) for k, v in item.items()}


def options(group: str, reg: registry.Registry | registry.Listing) -> list[str]:
    """Every option of ``group``: its registered components and its YAML files (presets such as ``pso_s1``)."""
    kind = GROUPS[group][0]
    names = set(configs.yaml_files(reg.searchpaths, group))
    if kind:
        names |= set(reg.names(kind))
    return sorted(names)


def help_text(reg: registry.Registry | registry.Listing | None = None) -> str:
    """The text of ``thermodrift run --help``; without ``reg``, from the saved listing of installed plugins."""
    reg = reg or registry.listing()
    chosen = defaults()
    lines = ["usage: thermodrift run [KEY=VALUE ...] [GROUP=OPTION ...] [-m] [--cfg job] [--hydra-help]", "",
             "One job = dataset -> split -> selector -> Optuna study of the model (optimizer = its sampler) ->",
             "held-out RMSE (µm) beside the persistence and MLR baselines, tracked in MLflow. With -m every",
             "comma-separated option list becomes a grid of jobs.", "", "examples:", EXAMPLES.rstrip(), "",
             "config groups (GROUP=OPTION; * = default):"]
    for group, (_, doc) in GROUPS.items():
        opts = [f"{o}*" if o == chosen.get(group) else o for o in options(group, reg)]
        lines.append(f"  {group:<11}{doc}")
        lines += textwrap.wrap(" ".join(opts), width=_WIDTH, initial_indent=" " * 13, subsequent_indent=" " * 13)
    lines += ["", "keys (KEY=VALUE; a group's settings as GROUP.params.NAME=VALUE, e.g. selector.params.k=6):"]
    width = max(len(k.path) for k in keys()) + 2
    for k in keys():
        head = f"  {k.path:<{width}}{k.default:<28} "
        lines += textwrap.wrap(plain(k.doc), width=_WIDTH, initial_indent=head, subsequent_indent=" " * len(head),
                               break_on_hyphens=False) or [head.rstrip()]
    lines += ["", "Hydra options: -m/--multirun, --cfg job|hydra|all, --resolve, --info, -cn/-cp, --hydra-help."]
    lines += [f"warning: plugin {key} failed to load and is left out: {error}" for key, error in reg.failures.items()]
    return "\n".join(lines)


# Hydra's options that take a value (`--cfg job`, `-cn name`, ...).
_VALUED = {"--cfg", "-c", "--package", "-p", "--config-path", "-cp", "--config-name", "-cn", "--config-dir", "-cd",
           "--experimental-rerun", "--info", "-i", "--shell-completion", "-sc"}


def split_flags(args: list[str]) -> tuple[list[str], list[str]]:
    """Hydra's options (with their values) and the overrides. Hydra's argparse reads options only before the
    overrides; users type them anywhere (`thermodrift run model=bp -m`), so they are moved first."""
    flags, rest, i = [], [], 0
    while i < len(args):
        arg = args[i]
        if arg.startswith("-"):
            flags.append(arg)
            if arg in _VALUED and i + 1 < len(args) and not args[i + 1].startswith("-") and "=" not in args[i + 1]:
                flags.append(args[i + 1])
                i += 1
        else:
            rest.append(arg)
        i += 1
    return flags, rest


# Hydra's own options; any other `--name` is a setting typed as an option.
_HYDRA_FLAGS = {"-h", "--help", "-m", "--multirun", "--resolve", "--hydra-help", "--version", "-r", "--run"} | _VALUED


def automl_overrides(args: list[str]) -> list[str]:
    """The ``run`` overrides of ``thermodrift automl args``: ``automl=default`` first unless an automl option is
    given."""
    given = any(a.startswith(("automl=", "experiment=automl")) for a in args)
    return list(args) if given else ["automl=default", *args]


# Hydra's modes, of which one command takes one: option -> its long name
_MODES = {"-r": "--run", "--run": "--run", "-m": "--multirun", "--multirun": "--multirun", "-c": "--cfg",
          "--cfg": "--cfg", "-i": "--info", "--info": "--info", "-sc": "--shell-completion",
          "--shell-completion": "--shell-completion"}


def check_flags(args: list[str], verb: str = "run") -> None:
    """Raise a one-line :class:`InputError` for a setting typed as an option (``--n-trials 5``), naming the
    override to write instead (``n_trials=5``; for ``automl``, ``--budget 5`` -> ``automl.budget_fits=5``), and for
    two of Hydra's modes in one command (``-m ... --cfg job``: a grid, or one job's configuration)."""
    modes = list(dict.fromkeys(_MODES[a.partition("=")[0]] for a in args if a.partition("=")[0] in _MODES))
    if "--multirun" in modes and len(modes) > 1:
        shown = [m for m in modes if m != "--multirun"][0]
        raise InputError(f"-m and {shown}: thermodrift {verb} runs a grid (-m) or shows one job ({shown}), not both",
                         hint=f"drop -m and give each option one value, e.g. thermodrift {verb} "
                         f"{'model=mlr ' if verb == 'run' else ''}--cfg job" if shown == "--cfg" else f"drop -m or {shown}")
    if len(modes) > 1:
        raise InputError(f"{' and '.join(modes)}: thermodrift {verb} takes one of them at a time",
                         hint=f"keep one of {', '.join(modes)}")
    i = 0
    while i < len(args):
        arg = args[i]
        name, _, value = arg.partition("=")
        if arg.startswith("-") and name not in _HYDRA_FLAGS:
            if not value and i + 1 < len(args) and not args[i + 1].startswith("-") and "=" not in args[i + 1]:
                value = args[i + 1]
            key = _setting(name.lstrip("-").replace("-", "_"), verb)
            raise InputError(f"{arg}: thermodrift {verb} takes settings as KEY=VALUE overrides, not as options",
                             hint=f"write {key}={value or '<value>'}" if key else f"see thermodrift {verb} --help")
        i += 2 if arg in _VALUED else 1


def _setting(word: str, verb: str) -> str | None:
    """The override key a user meant by ``--word``: a key whose last part is ``word`` or starts with it (automl's
    settings first for ``automl``), else the closest by spelling."""
    paths = [k.path for k in keys()] + list(GROUPS)
    automl = [f"automl.{k}" for k in GROUP_KEYS["automl"]]
    paths = automl + paths if verb == "automl" else paths + automl
    for match in (lambda last: last == word, lambda last: last.startswith(word)):
        found = [p for p in paths if match(p.split(".")[-1])]
        if found:
            return found[0]
    close = _did_you_mean(word, [p.split(".")[-1] for p in paths])
    return next((p for p in paths if close and close.endswith(f"'{p.split('.')[-1]}'?)")), None)


def check_overrides(overrides: list[str], reg: registry.Registry | registry.Listing) -> None:
    """Raise a one-line :class:`InputError` for an unknown group option or an unknown key, with the closest
    right one ("did you mean 'mlr'?") and the choices. Additions (``+key``), deletions (``~key``), Hydra's
    own settings and sweep expressions (``range(...)``, globs) are left to Hydra. A component's parameter names are
    checked from a :class:`~thermodrift.core.registry.Listing` (no plugin imported) as from the loaded
    :class:`~thermodrift.core.registry.Registry`."""
    groups = {g: options(g, reg) for g in GROUPS}
    given = {k: v for k, v in (o.split("=", 1) for o in overrides if "=" in o) if k in groups}
    chosen = {**defaults(), **_preset_groups(given.get("experiment", defaults().get("experiment"))), **given}
    known_keys = {k.path for k in keys()} | _preset_keys()
    top_level = {p.split(".")[0] for p in known_keys} | set(groups) | {"hydra"}
    for override in overrides:
        if "=" not in override or override[0] in "+~" or "/" in override.split("=", 1)[0]:
            continue
        key, value = override.split("=", 1)
        path = key.split(".")
        if key in groups:
            if not re.search(r"[()*?\[\]{}]", value):
                for option in value.split(","):
                    if option not in groups[key]:
                        raise InputError(f"{key}={option}: unknown {key} {option!r}"
                                         f"{_did_you_mean(option, groups[key])}; options: {', '.join(groups[key])}")
            continue
        if path[0] == "hydra":
            continue
        if path[0] not in top_level:
            raise InputError(f"{override}: unknown key {path[0]!r}{_did_you_mean(path[0], sorted(top_level))}; "
                             f"keys: {', '.join(sorted(top_level - {'hydra'}))}")
        section_keys = sorted(p.split(".", 1)[1] for p in known_keys if p.startswith(path[0] + "."))
        if section_keys and len(path) > 1 and path[1] not in section_keys:
            raise InputError(f"{override}: unknown key {key!r}{_did_you_mean(path[1], section_keys, path[0] + '.')}"
                             f"; keys of {path[0]}: {', '.join(section_keys)}")
        if path[0] in groups and len(path) > 1:
            _check_group_key(path, override, chosen.get(path[0]), reg)


def _check_group_key(path: list[str], override: str, option: str | None,
                     reg: registry.Registry | registry.Listing) -> None:
    group, kind, allowed = path[0], GROUPS[path[0]][0], GROUP_KEYS.get(path[0], [])
    if path[1] not in allowed:
        raise InputError(f"{override}: unknown key {'.'.join(path[:2])!r}"
                         f"{_did_you_mean(path[1], allowed, group + '.')}; keys of {group}: {', '.join(allowed)}")
    if path[1] != "params" or len(path) < 3 or not kind or not option or "," in option:
        return
    params = reg.params(kind, _component_name(group, option, reg))  # a Listing keeps them: no plugin imported
    if params is not None and path[2] not in params:
        raise InputError(f"{override}: {group} {option!r} has no parameter {path[2]!r}"
                         f"{_did_you_mean(path[2], sorted(params), f'{group}.params.')}; "
                         f"its parameters: {', '.join(sorted(params)) or 'none'}")


def _component_name(group: str, option: str, reg: registry.Registry | registry.Listing) -> str:
    """The registered name behind an option: a YAML's ``name`` (``pso_s1`` -> ``pso``), else the option."""
    found = configs.yaml_files(reg.searchpaths, group).get(option)
    if found is None:
        return option
    return (yaml.safe_load(found.read_text(encoding="utf-8")) or {}).get("name", option)


def _presets() -> dict[str, dict[str, Any]]:
    """Every experiment preset's YAML content by option name."""
    return {name: yaml.safe_load(path.read_text(encoding="utf-8")) or {}
            for name, path in configs.yaml_files([], "experiment").items()}


def _preset_keys() -> set[str]:
    """Top-level keys that experiment presets set (``ablation``)."""
    return {k for preset in _presets().values() for k in preset if k != "defaults"}


def _preset_groups(experiment: str | None) -> dict[str, str]:
    """The group options a preset selects in its defaults list (``override /dataset: fl_thermal``)."""
    listed = _presets().get(experiment or "", {}).get("defaults", [])
    return {k.removeprefix("override ").strip().lstrip("/"): v
            for item in listed if isinstance(item, dict) for k, v in item.items()}


def _did_you_mean(word: str, choices: list[str], prefix: str = "") -> str:
    """The closest choice by edit distance counting a swap of two neighbours as one edit (``mrl`` -> ``mlr``,
    not ``mnr``), within a third of the word's length; ties go to difflib's similarity."""
    limit = max(1, len(word) // 3)
    scored = [(_edits(word, c), -difflib.SequenceMatcher(None, word, c).ratio(), c) for c in choices]
    close = min((s for s in scored if s[0] <= limit), default=None)
    return f" (did you mean '{prefix}{close[2]}'?)" if close else ""


def _edits(a: str, b: str) -> int:
    """Optimal-string-alignment distance; difflib has no edit distance with transpositions, so it is here."""
    d = [[i + j if i * j == 0 else 0 for j in range(len(b) + 1)] for i in range(len(a) + 1)]
    for i in range(1, len(a) + 1):
        for j in range(1, len(b) + 1):
            d[i][j] = min(d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] != b[j - 1]))
            if i > 1 and j > 1 and a[i - 1] == b[j - 2] and a[i - 2] == b[j - 1]:
                d[i][j] = min(d[i][j], d[i - 2][j - 2] + 1)
    return d[len(a)][len(b)]
