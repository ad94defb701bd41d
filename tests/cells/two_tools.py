"""A cell with two tools (jaws and a suction cup) on a UR5e tool changer, for the tests."""


def changer_cell(name: str, tool: str, tools: str, rack: str, io: str, frames: str) -> str:
    """A UR5e on a table with a tool changer: the cell file around its ``tools:`` (indented
    entries), the rack mapping, the ``io:`` entries and the ``frames:`` (and what follows)."""
    return f"""\
cell: {name}
robot:
  model: ur5e
  backend: sim
  mount: {{xyz: [0, 0, 0.9], rpy: [0, 0, 180]}}
  home: [0, -90, 90, -90, -90, 0]
  tool: {tool}
  limits: {{joint_speed: 120, joint_accel: 300, tcp_speed: 0.8, margin: 0.9}}
tools:
{tools}tool_changer:
  lock: tool_lock
  locked: tool_locked
  rack: {rack}
io:
{io}fixtures:
  - {{name: table, box: {{size: [1.2, 1.2, 0.04]}}, pose: {{xyz: [0.3, 0, 0.88]}}}}
frames:
{frames}"""


CELL = changer_cell(
    "two-tools",
    "jaws",
    """\
  jaws:
    tcp: {xyz: [0, 0, 0.15]}
    payload: {mass: 1.0, cog: [0, 0, 0.05]}
    gripper: {kind: io, close: {output: jaws, value: true}, closed_sensor: jaws_closed, stroke: 0.06}
    geometry: [{cylinder: {radius: 0.035, length: 0.09}, xyz: [0, 0, 0.045]}]
  cup:
    tcp: {xyz: [0, 0, 0.22]}
    payload: {mass: 0.6, cog: [0, 0, 0.08]}
    gripper:
      kind: vacuum
      suction: {output: vacuum_on}
      vacuum_ok: vacuum_ok
      cups: [{xyz: [0, 0, 0], radius: 0.02}]
      holding_force: 40
    geometry: [{cylinder: {radius: 0.02, length: 0.2}, xyz: [0, 0, 0.1]}]
""",
    "{jaws: rack_jaws, cup: rack_cup}",
    """\
  outputs: {jaws: DO0, vacuum_on: DO1, tool_lock: DO4}
  inputs: {jaws_closed: DI0, vacuum_ok: DI1, tool_locked: DI4}
""",
    """\
  rack_jaws: {xyz: [0.25, 0.40, 1.05], rpy: [180, 0, 0]}
  rack_cup: {xyz: [0.40, 0.40, 1.12], rpy: [180, 0, 0]}
  spot: {xyz: [0.45, -0.2, 1.05], rpy: [180, 0, 0]}
  touch: {xyz: [0.45, -0.2, 0.91], rpy: [180, 0, 0]}    # 10 mm over the table
""",
)

#: touch the table with the mounted tool: only the cup (TCP 0.22 m, its face at the TCP)
#: meets the table 10 mm past the frame; the jaws' pads end 5 cm short of the cup's face
TOUCH = """\
task: touch
steps:
  - move: home
  - change_tool: cup
  - approach: {to: touch, distance: 0.03}
  - insert: {to: touch, depth: 0.02, speed: 0.01, force: {max: 10}, expect_depth: [0.007, 0.013]}
  - retreat: 0.05
  - change_tool: jaws
  - move: home
"""

TASK = """\
task: swap
steps:
  - move: home
  - change_tool: cup
  - move: spot
  - change_tool: jaws
  - move: home
"""

#: two jaw grippers on the changer, each with its own valve and sensor: only the wide one
#: takes the 60 mm block
TWO_JAWS = changer_cell(
    "two-jaws",
    "narrow",
    """\
  narrow:
    tcp: {xyz: [0, 0, 0.15]}
    payload: {mass: 1.0, cog: [0, 0, 0.05]}
    gripper: {kind: io, close: {output: narrow_close}, closed_sensor: narrow_closed, stroke: 0.04}
    geometry: [{cylinder: {radius: 0.035, length: 0.1}, xyz: [0, 0, 0.05]}]
  wide:
    tcp: {xyz: [0, 0, 0.18]}
    payload: {mass: 1.3, cog: [0, 0, 0.06]}
    gripper: {kind: io, close: {output: wide_close}, closed_sensor: wide_closed, stroke: 0.09}
    geometry: [{cylinder: {radius: 0.04, length: 0.13}, xyz: [0, 0, 0.065]}]
""",
    "{narrow: rack_narrow, wide: rack_wide}",
    """\
  outputs: {narrow_close: DO0, wide_close: DO2, tool_lock: DO4}
  inputs: {narrow_closed: DI0, wide_closed: DI2, tool_locked: DI4}
""",
    """\
  rack_narrow: {xyz: [0.25, 0.40, 1.05], rpy: [180, 0, 0]}
  rack_wide: {xyz: [0.40, 0.40, 1.08], rpy: [180, 0, 0]}
  infeed: {xyz: [0.45, -0.25, 0.93], rpy: [180, 0, 0]}
  drop: {xyz: [0.50, 0.05, 0.931], rpy: [180, 0, 0]}
parts:
  - {name: block, box: {size: [0.06, 0.06, 0.06]}, mass: 0.4, at: infeed}
""",
)

WIDE_PICK = """\
task: wide_pick
steps:
  - move: home
  - change_tool: wide
  - pick: {at: infeed, approach: 0.1, grip: {confirm: wide_closed, force: {min: 2, max: 10}}}
  - place: {at: drop, approach: 0.1}
  - change_tool: narrow
  - move: home
"""
