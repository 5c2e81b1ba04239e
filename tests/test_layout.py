"""Declared state (langenv.layout): fields, their tables, slots, packing."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from langenv.control.pacing import PACE_LAW
from langenv.errors import ConfigError
from langenv.layout import Field, Layout, field_table


def test_a_table_gives_each_field_its_size_kind_and_meaning() -> None:
    got = field_table(
        """
        p               physical pace
        end_tangent[3]  the direction of progress
                        once done
        n_legs:int      number of legs

        leg[2]:index    the legs
        """
    )
    assert got == (
        Field("p", doc="physical pace"),
        Field("end_tangent", 3, doc="the direction of progress once done"),
        Field("n_legs", kind="int", doc="number of legs"),
        Field("leg", 2, "index", "the legs"),
    )


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ("p  pace\n2x  bad", "line 2: '2x' is not NAME[SIZE]:KIND"),
        ("p[x]  pace", "line 1: 'p[x]'"),
        ("  continued\np  pace", "line 1: a continuation before any field"),
        ("p:complex  pace", "kind must be one of"),
        ("p[0]  pace", "size must be an int >= 1"),
        ("_p  pace", "public identifier"),
    ],
)
def test_a_malformed_table_is_refused_naming_the_line(table: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace("[", r"\[")):
        field_table(table)


def test_the_shipped_declarations_are_tables() -> None:
    assert [f.name for f in PACE_LAW][:2] == ["k_ca", "k_em"]
    assert all(f.doc for f in PACE_LAW)


def test_slots_follow_the_declaration_and_pack_round_trips() -> None:
    lay = Layout("demo", field_table("a  one\nv[3]  three\nk:int  n\ni:index  which"))
    assert (lay.at.a, lay.at.v, lay.at.k, lay.at.i, lay.size) == (0, 1, 4, 5, 6)
    arr = lay.pack(lay.zeros(), {"a": 0.5, "v": [1, 2, 3], "k": 7, "i": None})
    got = lay.unpack(arr)
    assert got["a"] == 0.5 and list(got["v"]) == [1, 2, 3]
    assert got["k"] == 7 and got["i"] is None
    assert lay.span("v", "k") == slice(1, 5)


def test_a_layout_refuses_a_name_twice_and_unknown_or_missing_values() -> None:
    with pytest.raises(ConfigError, match="declared twice"):
        Layout("twice", field_table("a  x"), field_table("a  y"))
    lay = Layout("demo", field_table("a  one\nv[3]  three"))
    with pytest.raises(ConfigError, match="no field 'b'"):
        lay.pack(lay.zeros(), {"b": 1.0})
    with pytest.raises(ConfigError, match="takes 3 values, got 2"):
        lay.pack(lay.zeros(), {"v": [1.0, 2.0]})
    with pytest.raises(ConfigError, match="no value for v"):
        lay.pack_all(lay.zeros(), {"a": 1.0})


@given(
    st.lists(
        st.tuples(st.integers(1, 4), st.sampled_from(["float", "int", "bool", "index"])),
        min_size=1,
        max_size=8,
    )
)
def test_any_table_places_its_fields_end_to_end(spec: list[tuple[int, str]]) -> None:
    lines = [f"f{k}[{size}]:{kind}  field {k}" for k, (size, kind) in enumerate(spec)]
    lay = Layout("any", field_table("\n".join(lines)))
    starts = np.cumsum([0] + [size for size, _ in spec])
    assert [lay.slot(f"f{k}") for k in range(len(spec))] == list(starts[:-1])
    assert lay.size == starts[-1]


def test_a_record_table_gives_each_array_its_dtype() -> None:
    from langenv.kernels.views import ArrayField, array_table

    got = array_table("es  the env's array\nkids:int64  the children\n  of each vertex")
    assert got == (
        ArrayField("es", "float64", "the env's array"),
        ArrayField("kids", "int64", "the children of each vertex"),
    )
    with pytest.raises(ConfigError, match="dtype must be one of"):
        array_table("kids:int8  the children")
    with pytest.raises(ConfigError, match="line 1: 'kids\\[2\\]' is not NAME:DTYPE"):
        array_table("kids[2]  the children")
