"""The base of every configuration model: unknown keys, changes after loading and non-finite
numbers are all refused, so a typo or a NaN in a file is an error that names its key."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class StrictModel(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
