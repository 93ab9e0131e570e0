"""Constructor parameters checked before a component exists.

Amaranth warns ("created but never used", ``UnusedElaboratable``) when an elaboratable is
garbage-collected without being elaborated. A component that rejects its parameters inside
``__init__`` has already been created, so the rejection would also print that warning, which
blames the caller for something it did not do. Amaranth has no public switch to mark one object
as intentionally unused, so the check runs earlier instead: :class:`CheckedParameters` binds the
constructor's arguments to ``__init__``'s signature in ``__new__`` and calls the class's
:meth:`~CheckedParameters.check_parameters` before the object is made. A bad parameter raises
``ValueError`` and no component ever exists.

Put the mixin first among the bases (``class Unit(CheckedParameters, wiring.Component)``) and
define ``check_parameters`` as a classmethod taking ``__init__``'s parameters by name (defaults
applied). Subclasses with a narrower constructor inherit the check through their own signature.
"""

from __future__ import annotations

import inspect

__all__ = ["CheckedParameters"]


class CheckedParameters:
    """Mixin: ``cls.check_parameters(**arguments)`` runs before the elaboratable is created."""

    def __new__(cls, *args, src_loc_at: int = 0, **kwargs):
        signature = inspect.signature(cls.__init__)
        bound = signature.bind(None, *args, **kwargs)
        bound.apply_defaults()
        arguments = dict(bound.arguments)
        arguments.pop(next(iter(signature.parameters)))  # self
        for name, parameter in signature.parameters.items():
            if parameter.kind is inspect.Parameter.VAR_KEYWORD:
                arguments.update(arguments.pop(name, {}))
        cls.check_parameters(**arguments)
        # one frame deeper than a plain construction: the creator is our caller's caller
        return super().__new__(cls, *args, src_loc_at=src_loc_at + 1, **kwargs)

    @classmethod
    def check_parameters(cls, **arguments) -> None:
        """Raise ``ValueError`` naming the parameter if ``arguments`` cannot build the unit."""
