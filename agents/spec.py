"""The agent grammar every command uses: one string names an agent and how to build it for an env.

::

    px4                      PX4 v1.13 cascade (PX4Agent), S500 parameters
    px4(MPC_XY_P=1.2)        ... with PX4 parameter overrides (upper-case PX4 names) or PX4Agent options
    px4+<observer>           PX4 + disturbance-observer feedforward F = F0 - phi_hat, tau = tau0 - tau_hat
                             (Wang et al. 2024, Sec. 7.2) from any registered observer (px4+ffts_eso, px4+geso, ...)
    px4+geso(order=3)        ... with keyword overrides: observer gains, PX4 parameters (upper case),
                             force_ff / torque_ff, PX4Agent options (position_rate, ...)
    module:Class             a user's own Agent subclass (plugin), optionally module:Class(key=value, ...)
    sb3:PATH                 a policy trained by ``fawtgym train`` (a run folder, or one of its checkpoints)

Values in parentheses are Python literals (numbers, True/False, 'strings', lists).  ``px4+ffts_eso``
uses the flight gains of Wang et al. (2024), Sec. 7.2 unless overridden.  Several agents are
separated by commas (commas inside parentheses belong to the agent).

Plugins: ``module:Class`` imports ``module`` (it must be importable: installed, or on ``PYTHONPATH``)
and builds ``Class.for_env(env, **kwargs)`` (the :class:`~fawtgym.agents.base.Agent` default calls
``Class(**kwargs)``).  The class must subclass :class:`~fawtgym.agents.base.Agent`, act on batched
infos (a leading row axis) and accept ``reset(info, seed=None, rows=mask)``.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import re
import sys
from collections.abc import Mapping
from typing import Any

from fawtgym.core.checks import listed, shown

from .base import Agent

#: FFTS-ESO gains of the flight experiment, Wang et al. (2024) Sec. 7.2 (the paper's "k_r" are k_t here)
FFTS_ESO_FLIGHT_GAINS: dict[str, float] = dict(p=1.2, kt1=6.0, kt2=3.0, kt3=1.0, kappa_t=0.6, ka1=8.0, ka2=4.0,
                                               ka3=2.0, kappa_a=0.6)
#: observer gains an agent name implies unless overridden
DEFAULT_OBSERVER_KWARGS: dict[str, dict[str, Any]] = {"ffts_eso": FFTS_ESO_FLIGHT_GAINS}
#: keyword arguments of PX4Agent / PX4ObserverAgent a spec may set (others are PX4 parameters or observer gains)
_AGENT_OPTIONS = ("rate_loop_rate", "attitude_rate", "position_rate", "yaw_setpoint", "hover_thrust", "gyro_key",
                  "force_ff", "torque_ff", "px4_version", "pose_latency", "observer_inputs", "thrust_model_error")
_PX4_PARAM = re.compile(r"[A-Z][A-Z0-9_]*")
_HEAD = re.compile(r"\s*([^()]+?)\s*(?:\((.*)\))?\s*")
GRAMMAR = "px4, px4+<observer>, px4+<observer>(key=value, ...), module:Class, sb3:PATH"


@dataclasses.dataclass(frozen=True)
class AgentSpec:
    """A parsed agent name: ``kind`` in {"px4", "px4+observer", "plugin", "sb3"}; ``observer`` (px4+observer) and
    ``target`` (plugin ``module:Class``, sb3 run path) are "" where the kind has none."""

    kind: str
    observer: str = ""
    target: str = ""
    kwargs: tuple[tuple[str, Any], ...] = ()

    @property
    def name(self) -> str:
        """The canonical text (keyword overrides sorted), used as the agent's name everywhere."""
        head = {"px4": "px4", "px4+observer": f"px4+{self.observer}", "plugin": self.target,
                "sb3": f"sb3:{self.target}"}[self.kind]
        if not self.kwargs:
            return head
        return f"{head}({', '.join(f'{k}={v!r}' for k, v in self.kwargs)})"

    def __str__(self) -> str:
        return self.name


def split_agents(text: str) -> list[str]:
    """Split a comma list of agent names, keeping commas inside parentheses."""
    out: list[str] = []
    cur: list[str] = []
    depth = 0
    for ch in text:
        if ch == "," and depth == 0:
            out.append("".join(cur).strip())
            cur = []
            continue
        depth += (ch == "(") - (ch == ")")
        if depth < 0:
            raise ValueError(f"unbalanced ')' in agent list {shown(text)}")
        cur.append(ch)
    if depth:
        raise ValueError(f"unbalanced '(' in agent list {shown(text)}")
    out.append("".join(cur).strip())
    return [s for s in out if s]


def _parse_kwargs(text: str, where: str) -> tuple[tuple[str, Any], ...]:
    try:
        call = ast.parse(f"f({text})", mode="eval").body
    except SyntaxError as exc:
        if "digits" in str(exc):  # Python's int-to-str limit, raised while parsing a literal
            raise ValueError(f"agent {shown(where)}: an override's value is an int of more than "
                             f"{sys.get_int_max_str_digits()} digits, beyond any option's range") from None
        raise ValueError(f"agent {shown(where)}: cannot read the keyword overrides {shown(text)}; write "
                         "key=value, ... with Python literals") from None
    # one group of overrides: "px4(A=1)(B=2)" parses as a call of a call, which would drop A
    if not isinstance(call, ast.Call) or call.args or not isinstance(call.func, ast.Name):
        raise ValueError(f"agent {shown(where)}: overrides must be one group of key=value pairs, got "
                         f"{shown(text)}")
    out = {}
    for kw in call.keywords:
        if kw.arg is None:
            raise ValueError(f"agent {shown(where)}: overrides must be key=value pairs, got {shown(text)}")
        if kw.arg in out:
            raise ValueError(f"agent {shown(where)}: {kw.arg} is given twice; give each override once")
        try:
            out[kw.arg] = ast.literal_eval(kw.value)
        except ValueError:
            raise ValueError(f"agent {shown(where)}: the value of {kw.arg} must be a Python literal (number, "
                             f"True/False, 'string', list), got {ast.unparse(kw.value)}") from None
        try:  # the canonical name holds its repr: refused if it has none (an int beyond Python's int-to-str limit)
            repr(out[kw.arg])
        except ValueError:
            raise ValueError(f"agent {shown(where)}: the value of {kw.arg} is {shown(out[kw.arg])}, beyond any "
                             "option's range") from None
    return tuple(sorted(out.items()))


def parse_agent(text: str) -> AgentSpec:
    """Parse one agent name of the grammar; ValueError naming the bad part and what exists."""
    from fawtgym.observers import observer_names

    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"agent name must be a non-empty string ({GRAMMAR}), got {shown(text)}")
    text = text.strip()
    if text.startswith("sb3:"):
        path = text[4:].strip()
        if not path:
            raise ValueError(f"agent {shown(text)}: sb3:PATH needs the path of a saved policy")
        return AgentSpec("sb3", target=path)
    m = _HEAD.fullmatch(text)
    if m is None:
        raise ValueError(f"agent {shown(text)} does not follow the grammar: {GRAMMAR}")
    head, args = m.group(1), m.group(2)
    kwargs = _parse_kwargs(args, text) if args is not None and args.strip() else ()
    if ":" in head:
        module, _, cls = head.partition(":")
        if not (module and cls.isidentifier() and all(p.isidentifier() for p in module.split("."))):
            raise ValueError(f"agent {shown(text)}: a plugin is module:Class (e.g. mypkg.agents:MyAgent)")
        return AgentSpec("plugin", target=head, kwargs=kwargs)
    if head == "px4":
        return AgentSpec("px4", kwargs=kwargs)
    if head.startswith("px4+"):
        obs = head[4:]
        if obs not in observer_names():
            raise ValueError(f"agent {shown(text)}: unknown observer {shown(obs)}; registered observers: "
                             f"{', '.join(observer_names())}")
        return AgentSpec("px4+observer", observer=obs, kwargs=kwargs)
    valid = ["px4"] + [f"px4+{o}" for o in observer_names()]
    raise ValueError(f"unknown agent {shown(text)}; valid: {', '.join(valid)}, module:Class, sb3:PATH")


def parse_agents(text: str) -> list[AgentSpec]:
    """A comma list of agent names -> specs (duplicates refused)."""
    specs = [parse_agent(s) for s in split_agents(text)]
    if not specs:
        raise ValueError(f"no agent given; valid: {GRAMMAR}")
    names = [s.name for s in specs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"agent(s) {dup} given twice")
    return specs


def _split_px4_kwargs(spec: AgentSpec) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    """(PX4 parameter overrides, agent options, observer kwargs) of a px4 / px4+observer spec."""
    params, options, observer = {}, {}, {}
    for k, v in spec.kwargs:
        if _PX4_PARAM.fullmatch(k):
            params[k] = v
        elif k in _AGENT_OPTIONS:
            options[k] = v
        elif spec.kind == "px4+observer":
            observer[k] = v
        else:
            raise ValueError(f"agent {shown(spec.name)}: unknown option {shown(k)}; px4 takes PX4 parameters "
                             f"(upper-case names, "
                             f"e.g. MPC_XY_P) and {', '.join(_AGENT_OPTIONS[:6])}")
    if spec.kind == "px4" and ({"force_ff", "torque_ff"} & set(options)):
        raise ValueError(f"agent {shown(spec.name)}: force_ff/torque_ff need an observer (px4+<observer>)")
    return params, options, observer


def make_agent(spec: AgentSpec | str, env: Any) -> Agent:
    """Build the agent ``spec`` names, matched to ``env`` (vehicle preset, control rate, set point).

    Errors (unknown parameter or gain, a plugin that cannot be imported or is not an Agent) are a one-line
    ValueError naming the agent.
    """
    if isinstance(spec, str):
        spec = parse_agent(spec)
    if spec.kind == "sb3":
        from .sb3_agent import SB3Agent

        try:
            return SB3Agent.for_env(env, spec.target, **dict(spec.kwargs))
        except ImportError as exc:
            raise ValueError(f"agent {shown(spec.name)} needs Stable-Baselines3: pip install 'fawtgym[rl]' "
                             f"({exc})") from exc
        except ValueError as exc:
            msg = str(exc).removeprefix("sb3 agent: ")
            raise ValueError(f"agent {shown(spec.name)}: {msg}") from exc
    if spec.kind == "plugin":
        cls = _import_plugin(spec)
        try:
            agent = cls.for_env(env, **dict(spec.kwargs))
        except TypeError as exc:
            raise ValueError(f"agent {shown(spec.name)}: cannot build it: {exc}") from exc
        if not isinstance(agent, Agent):
            raise ValueError(f"agent {shown(spec.name)}: {cls.__name__}.for_env returned {type(agent).__name__}, "
                             "not an Agent")
        return agent
    from .px4_agent import PX4Agent, PX4ObserverAgent
    from .px4_params import PX4Params

    params, options, obs_kwargs = _split_px4_kwargs(spec)
    if obs_kwargs:
        _check_observer_kwargs(spec, obs_kwargs)
    try:
        px4_params = PX4Params.s500(**params) if params else None
        if spec.kind == "px4":
            return PX4Agent.for_env(env, params=px4_params, **options)
        gains = {**DEFAULT_OBSERVER_KWARGS.get(spec.observer, {}), **obs_kwargs}
        return PX4ObserverAgent.for_env(env, observer=spec.observer, observer_kwargs=gains or None,
                                        params=px4_params, **options)
    except (ValueError, TypeError, KeyError) as exc:
        msg = (exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)).splitlines()[0]
        raise ValueError(f"agent {shown(spec.name)}: {msg}") from exc


def _check_observer_kwargs(spec: AgentSpec, kwargs: Mapping[str, Any]) -> None:
    """Unknown observer gains name the observer's valid keywords."""
    from fawtgym.observers.base import observer_options

    valid = observer_options(spec.observer)
    if valid is None:  # it takes any keyword
        return
    unknown = set(kwargs) - set(valid)
    if unknown:
        raise ValueError(f"agent {shown(spec.name)}: unknown option(s) {listed(unknown)} for observer {spec.observer}; "
                         f"its gains: {', '.join(valid)}; PX4 parameters are upper case; agent options: "
                         f"{', '.join(_AGENT_OPTIONS)}")


def agent_action_type(spec: AgentSpec | str) -> str:
    """The env action type (``motors`` or ``ctbr``) the agent ``spec`` names flies, known before building it (the
    runner builds the env to match): PX4 agents fly motors, a plugin its class's ``action_type``, an ``sb3:`` run
    what it was trained on."""
    if isinstance(spec, str):
        spec = parse_agent(spec)
    if spec.kind == "sb3":
        from .sb3_agent import run_action_type

        try:
            return run_action_type(spec.target)
        except ValueError as exc:
            raise ValueError(f"agent {shown(spec.name)}: {str(exc).removeprefix('sb3 agent: ')}") from exc
    if spec.kind == "plugin":
        return getattr(_import_plugin(spec), "action_type", "motors")
    return "motors"


def _import_plugin(spec: AgentSpec) -> type[Agent]:
    module_name, _, cls_name = spec.target.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ValueError(f"agent {shown(spec.name)}: cannot import module {shown(module_name)} ({exc}); is it "
                         f"installed or on PYTHONPATH?") from exc
    cls = getattr(module, cls_name, None)
    if cls is None:
        found = sorted(k for k, v in vars(module).items() if isinstance(v, type) and issubclass(v, Agent)
                       and v is not Agent)
        raise ValueError(f"agent {shown(spec.name)}: module {shown(module_name)} has no {shown(cls_name)}; Agent "
                         f"classes in it: {found or 'none'}")
    if not (isinstance(cls, type) and issubclass(cls, Agent)):
        raise ValueError(f"agent {shown(spec.name)}: {cls_name} is not a subclass of fawtgym.agents.Agent")
    return cls


def observer_kwargs_of(spec: AgentSpec) -> Mapping[str, Any]:
    """The observer gains a px4+observer spec flies with (defaults merged with overrides)."""
    if spec.kind != "px4+observer":
        return {}
    return {**DEFAULT_OBSERVER_KWARGS.get(spec.observer, {}), **_split_px4_kwargs(spec)[2]}
