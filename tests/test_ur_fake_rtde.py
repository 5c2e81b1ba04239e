"""The fake ur-rtde matches the real library's signatures (names, order, defaults, positional-only).

The reference is the installed ``ur-rtde`` (``pip install -e ".[ur]"``): its pybind signature
lines. An argument it leaves unnamed (``arg0``) is positional-only; the fake must agree.
"""

from __future__ import annotations

import inspect
import re

import pytest

from langenv.robot.ur import fake_rtde

MODULES = {
    "RTDEControlInterface": "rtde_control",
    "RTDEReceiveInterface": "rtde_receive",
    "DashboardClient": "dashboard_client",
}


def _real_params(doc: str, name: str) -> list[tuple[str, str | None]]:
    """(name, default text) of each argument after ``self`` in the overload taking the most."""
    best: list[tuple[str, str | None]] | None = None
    for line in doc.splitlines():
        m = re.match(rf"(?:\d+\. )?{name}\(self: [\w.]+(.*)\) -> ", line.strip())
        if not m:
            continue
        params = []
        for part in re.split(r", (?=\w+: )", m.group(1).lstrip(", ")) if m.group(1) else []:
            pname, _, rest = part.partition(": ")
            default = rest.split(" = ", 1)[1] if " = " in rest else None
            params.append((pname, default))
        if best is None or (params and params[0][0] == "pose"):
            best = params
    assert best is not None, f"no signature for {name}"
    return best


def _same_default(real: str | None, fake: object) -> bool:
    if real is None:
        return fake is inspect.Parameter.empty
    if real.startswith("<Flags."):
        return int(real.rsplit(":", 1)[1].rstrip(">")) == fake
    return str(eval(real)) == str(fake)  # numbers, booleans, []


@pytest.mark.parametrize("cls_name", list(MODULES))
def test_fake_signatures_match_ur_rtde(cls_name: str) -> None:
    real_mod = pytest.importorskip(MODULES[cls_name])
    real_cls = getattr(real_mod, cls_name)
    fake_cls = getattr(fake_rtde, cls_name)
    names = [n for n, v in vars(fake_cls).items() if callable(v) and not n.startswith("_")]
    for name in [*names, "__init__"]:
        real = _real_params(getattr(real_cls, name).__doc__, name)
        fake = list(inspect.signature(getattr(fake_cls, name)).parameters.values())[1:]
        assert [p.name for p in fake] == [n for n, _ in real], f"{cls_name}.{name}"
        for p, (rname, rdefault) in zip(fake, real, strict=True):
            positional_only = rname.startswith("arg")
            assert (p.kind is inspect.Parameter.POSITIONAL_ONLY) == positional_only, (
                f"{cls_name}.{name}({rname})"
            )
            assert _same_default(rdefault, p.default), f"{cls_name}.{name}({rname}) default"


def test_the_fake_watchdog_stops_the_script_as_ur_rtde_does() -> None:
    """setWatchdog(f): no command for 1/f s stops the control script (action "stop"); reading
    the state is no command; afterwards commands answer False."""
    with fake_rtde.FakeUR("127.0.0.1") as ur:
        c = fake_rtde.RTDEControlInterface("127.0.0.1", 500.0)
        r = fake_rtde.RTDEReceiveInterface("127.0.0.1", 500.0)
        assert c.setWatchdog(50.0)
        for _ in range(30):  # kicked every period: runs on
            assert c.kickWatchdog()
            c.waitPeriod(c.initPeriod())
        assert c.isProgramRunning()
        for _ in range(11):  # 22 ms of reads only
            r.getActualTCPPose()
            c.waitPeriod(c.initPeriod())
        assert not c.isProgramRunning()
        assert ("watchdog", ur.period_index - 1) in ur.commands
        assert c.speedL([0.01, 0, 0, 0, 0, 0], 1.0, 0.002) is False
        assert c.speedStop(2.0) is False and c.setWatchdog(50.0) is False
