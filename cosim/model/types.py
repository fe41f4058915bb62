"""The FMI types of a variable and the master's kinds of them, named in one place (no heavy imports: the
checks of formulas and conditions read the kinds too).

A variable's FMI type is the one its model description declares (FMI 2.0: Real, Integer, Enumeration,
Boolean, String; FMI 3.0: Float64, Float32, Int8 ... UInt64, Enumeration, Boolean, String, Binary, Clock);
its kind is the master's grouping of them (FMI 2.0's types are their own kind; FMI 3.0's are mapped by
:data:`KINDS`)."""
from __future__ import annotations

#: The master's kind of a variable -> the Python types a scenario value of that variable may have.
PY_TYPES: dict[str, tuple[type, ...]] = {"Real": (float, int), "Integer": (int,), "Enumeration": (int,),
                                          "Boolean": (bool,), "String": (str,), "Binary": (str,)}
#: FMI 3.0 types -> the master's kind (FMI 2.0 types are their own kind).
KINDS: dict[str, str] = {"Float64": "Real", "Float32": "Real", "Int8": "Integer", "UInt8": "Integer",
                         "Int16": "Integer", "UInt16": "Integer", "Int32": "Integer", "UInt32": "Integer",
                         "Int64": "Integer", "UInt64": "Integer", "Enumeration": "Enumeration",
                         "Boolean": "Boolean", "String": "String", "Binary": "Binary", "Clock": "Clock"}
#: The FMI type of a 64-bit float by FMI version (FMI 2.0's Real is a C double).
FLOAT64: dict[int, str] = {2: "Real", 3: "Float64"}
#: The FMI types that are a 64-bit float (the values of :data:`FLOAT64`).
FLOAT64_TYPES: frozenset[str] = frozenset(FLOAT64.values())
#: The master's kinds whose values are integers (an enumeration's value is its integer).
INTEGER_KINDS: tuple[str, ...] = ("Integer", "Enumeration")
#: The master's kinds whose values are numbers (a range, a bias, a comparison apply).
NUMERIC_KINDS: tuple[str, ...] = ("Real", *INTEGER_KINDS)
#: The master's kinds whose values are text (a string, FMI 3.0's binary as its text).
TEXT_KINDS: tuple[str, ...] = ("String", "Binary")
#: Ranges of the FMI integer types (FMI 2.0 Integer is 32 bits).
INT_RANGES: dict[str, tuple[int, int]] = {
    "Integer": (-2 ** 31, 2 ** 31 - 1), "Int8": (-2 ** 7, 2 ** 7 - 1), "UInt8": (0, 2 ** 8 - 1),
    "Int16": (-2 ** 15, 2 ** 15 - 1), "UInt16": (0, 2 ** 16 - 1), "Int32": (-2 ** 31, 2 ** 31 - 1),
    "UInt32": (0, 2 ** 32 - 1), "Int64": (-2 ** 63, 2 ** 63 - 1), "UInt64": (0, 2 ** 64 - 1)}
