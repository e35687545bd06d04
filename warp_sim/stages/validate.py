"""Validate a USD stage with every validator registered in ``pxr.UsdValidation``."""

from __future__ import annotations

import os

from pxr import Usd, UsdValidation

__all__ = ["validate_stage"]


def validate_stage(path_or_stage) -> list[str]:
    """Run all registered UsdValidation validators on a stage; return its error messages.

    ``path_or_stage`` is a ``Usd.Stage`` or a path to a USD file. Only errors
    (``ValidationErrorType.Error``) are returned, each as
    ``ValidationError.GetErrorAsString()`` (validator name, error name and
    message); warnings and infos are advisory and are dropped. An empty list
    means the stage is valid. A missing file raises ``FileNotFoundError``.
    """
    if isinstance(path_or_stage, Usd.Stage):
        stage = path_or_stage
    else:
        path = os.fspath(path_or_stage)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"validate_stage: no USD file at {path!r}")
        stage = Usd.Stage.Open(path)
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errors = UsdValidation.ValidationContext(validators).Validate(stage)
    return [e.GetErrorAsString() for e in errors
            if e.GetType() == UsdValidation.ValidationErrorType.Error]
