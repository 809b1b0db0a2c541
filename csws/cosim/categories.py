"""Which category of GB/T 15089 a SUMO vehicle is: from its vehicle class, or declared on its type.

The standard covers M, N and O vehicles (clause 1); SUMO's classes map to them as
below. Other classes (two-wheelers, rail, pedestrians, ships, ...) are outside the
system's scope and are not evaluated. A vehicle type may declare its category with
the parameter ``csws.category`` (for example ``M2`` for a minibus, which SUMO has no
class for); the declaration wins over the class.
"""

from __future__ import annotations

from csws.standard import Category

__all__ = ["CATEGORY_PARAMETER", "VCLASS_CATEGORY", "category_of"]

#: vType parameter that declares a type's category.
CATEGORY_PARAMETER = "csws.category"

#: SUMO vehicle class -> category.
VCLASS_CATEGORY: dict[str, Category] = {
    **dict.fromkeys(
        (
            "passenger",
            "private",
            "taxi",
            "evehicle",
            "hov",
            "emergency",
            "authority",
            "army",
            "vip",
            "custom1",
            "custom2",
        ),
        Category.M1,
    ),
    "bus": Category.M3,
    "coach": Category.M3,
    "delivery": Category.N,
    "truck": Category.N,
    "trailer": Category.O,
}


def category_of(vclass: str, declared: str = "") -> Category | None:
    """The category of a vehicle type: ``declared`` (the ``csws.category`` parameter) if set, else by class.

    Returns None for a class the standard does not cover.

    Raises
    ------
    ValueError
        When ``declared`` is not a category.
    """
    if declared.strip():
        try:
            return Category.parse(declared)
        except ValueError as exc:
            raise ValueError(f"vType parameter {CATEGORY_PARAMETER}: {exc}") from None
    return VCLASS_CATEGORY.get(vclass)
