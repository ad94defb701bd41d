"""The step kinds: one module each (``move.py``, ``pick.py``, ...), holding one
:class:`~cellrunner.model.step_kinds.StepKindDef` subclass registered with
:func:`~cellrunner.model.step_kinds.register`. Every module here whose name does not start
with ``_`` is a kind; :data:`~cellrunner.model.step_kinds.STEP_KINDS` finds them all.
``_families.py`` holds what the motion kinds share. docs/adding-a-step.md tells how to
add one."""
