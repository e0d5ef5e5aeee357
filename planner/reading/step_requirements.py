"""Specifications with `before`: a state the model requires before some steps (issue 28).

    - name: hands_on_r2_only_with_its_tools_idle
      display: "a person works on robot 2 only with its tools idle"
      before: [operator.move_r2_home, operator.reset_r2_tc]
      invariant: "!(nr.at == r2 && (nr.is_running || nr.run_forward))"

is not a state invariant: the named steps (a person's hands on a machine) may be taken only
in states where the invariant holds.  It compiles into those steps' guards, so plans, the
supervisor and the runner follow it as they follow any guard, and the station keeps it to
say on the cards why the machine is made safe first.
"""

from __future__ import annotations

from collections.abc import Sequence

import yaml

from planner.model.expression_text import Scope
from planner.model.expressions import Expr, conjunction
from planner.model.flat import Transition
from planner.model.station import StepRequirement
from planner.reading.flat import read_description, read_display
from planner.reading.yaml_reader import Reader

STEP_KEYS = ("name", "invariant", "before", "description", "display")


def read_step_requirement(
    reader: Reader, node: yaml.Node, scope: Scope
) -> tuple[StepRequirement, list[yaml.Node]] | None:
    """One specification with `before`, and the nodes of the step names (for errors)."""
    fields = reader.mapping(
        node, "a specification", STEP_KEYS, required=("name", "invariant", "before")
    )
    if fields is None or not {"name", "invariant", "before"} <= fields.keys():
        return None
    name = reader.name(fields["name"][1], "specification name")
    requires = reader.expression(
        fields["invariant"][1], scope, f"the invariant of specification '{name}'"
    )
    step_nodes = reader.sequence(fields["before"][1], "before")
    steps = [reader.name(n, "step name") for n in step_nodes]
    if name is None or requires is None or None in steps:
        return None
    if not steps:
        reader.error(fields["before"][1], f"specification '{name}': 'before' names no step")
        return None
    what = f"specification '{name}'"
    requirement = StepRequirement(
        name,
        requires,
        tuple(s for s in steps if s is not None),
        reader.at(node),
        read_description(reader, fields),
        read_display(reader, fields, what),
    )
    return requirement, step_nodes


def guarded(
    reader: Reader,
    transitions: Sequence[tuple[Transition, yaml.Node]],
    requirements: Sequence[tuple[StepRequirement, list[yaml.Node]]],
) -> list[tuple[Transition, yaml.Node]]:
    """The transitions with each requirement conjoined to the guards of the steps it names;
    a name that is no transition is an error at that name."""
    index = {t.name: k for k, (t, _) in enumerate(transitions)}
    extra: dict[str, list[Expr]] = {}
    for requirement, nodes in requirements:
        for step, node in zip(requirement.steps, nodes, strict=True):
            if step not in index:
                reader.error(
                    node,
                    f"specification '{requirement.name}': 'before' names '{step}', which is "
                    "not a transition of the model",
                )
                continue
            extra.setdefault(step, []).append(requirement.requires)
    out = []
    for transition, node in transitions:
        more = extra.get(transition.name)
        if more:
            guard = conjunction([transition.guard, *more])
            transition = Transition(
                transition.name,
                transition.kind,
                guard,
                transition.actions,
                transition.source,
                transition.description,
                transition.display,
                transition.safety,
            )
        out.append((transition, node))
    return out
