"""Wire models of found bindings: a planner that solved its task stores the binding list it
found, so that planners of the same task on the same knowledge base can try it at once
(`knowledge.follow_found`), and a user can see what was solved."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from contract.models import MAX_LABEL, MAX_SEED, Label, Text, Value, _Strict

MAX_BINDINGS_PAGE = 100
SKELETON_EXAMPLE = "3f0c" * 16


class BindingIn(_Strict):
    """`skeleton`: a digest of the task's plan skeleton (`planner.skeleton`), so that only
    planners whose decisions mean the same take it up; `bindings`: every decision's value."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "task": "desk",
                    "skeleton": SKELETON_EXAMPLE,
                    "run": "desk-cp-bo-7",
                    "rollout": 12,
                    "bindings": {"#dir1": "front", "#pose12": [0.2, 0.8, 0.5]},
                }
            ]
        }
    )

    task: Label = Field(description="The task's name.")
    skeleton: Label = Field(description="A digest of the task's plan skeleton.")
    run: Text | None = Field(
        default=None, max_length=MAX_LABEL, description="The run that found it."
    )
    rollout: int | None = Field(
        default=None, ge=0, le=MAX_SEED, description="The rollout that found it."
    )
    bindings: dict[Label, Value] = Field(
        min_length=1, max_length=256, description="Every decision's value."
    )
    key: Annotated[Text, Field(min_length=1, max_length=200)] | None = Field(
        default=None,
        description="Idempotency key: the same key and binding again stores nothing and "
        "answers the stored one; the same key with another binding is a 409.",
    )


class BindingOut(BaseModel):
    binding_id: int
    task: str
    skeleton: str
    run: str | None = None
    rollout: int | None = None
    bindings: dict[str, Value]
    created_at: datetime | None = None


class BindingsPage(BaseModel):
    """`cursor`: the `after` of the next request (the highest id read, or the one given)."""

    bindings: list[BindingOut]
    cursor: int
