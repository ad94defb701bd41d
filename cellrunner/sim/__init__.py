"""The MuJoCo world of a cell: its description, its MJCF model and its physics.

Used by the ``sim`` backend (:mod:`cellrunner.backends.sim`) and by the virtual UR
controller (:mod:`cellrunner.twin`). Importing this package does not import MuJoCo;
:mod:`.mjcf`, :mod:`.world` and :mod:`.render` load it lazily when a model is built or
rendered.

- :mod:`.description` -- :class:`TwinDescription` and friends, what the world is built from
- :mod:`.from_cell` -- the description of a loaded cell file
- :mod:`.mjcf` -- the MJCF model of a description
- :mod:`.world` -- :class:`SimWorld`, the physics stepped one controller period at a time,
  with its parts: :mod:`.wrist` (the force/torque sensor), :mod:`.contacts` (contact
  rules, the place check), :mod:`.jaws`, :mod:`.faults` (grip_miss, part_slip),
  :mod:`.safety` (stop ramps), :mod:`.servo` (set-point interpolation), :mod:`.model_ids`
- :mod:`.vacuum`, :mod:`.tool_changer`, :mod:`.input_rules`, :mod:`.mesh_pieces` -- the
  parts of the world a cell may add
- :mod:`.render` -- offscreen PNGs for dry-run reports; :mod:`.cameras` -- the cell's cameras
- :mod:`.demo` -- a demo cell and demo motions for tests and benchmarks
- :mod:`.mujoco_loader` -- the one place MuJoCo is imported (GL off unless pictures are asked for)

Other packages use the world through its public methods and attributes only
(``tests/test_package_boundaries.py`` checks that no module reaches into its privates).
"""
