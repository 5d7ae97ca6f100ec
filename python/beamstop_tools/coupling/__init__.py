"""The controller-coupling example (issue 9, item 5): a PD controller on the
hub angle slews RotatingBeamImpact.fmu until its tip rests against the
surface, stepped by fmpy and by OSP libcosim.

- `controller`: the Python mirror of PDController.fmu's law, and the build
  of PDController.fmu from examples/coupling/pd_controller;
- `system`: examples/coupling/OspSystemStructure.xml read for both masters;
- `runs`: the fmpy loop (Jacobi or Gauss-Seidel ordering) and the libcosim run;
- `pd_slew`: the example: runs, figures, CSV and PNG
  (`python -m beamstop_tools.coupling.pd_slew`, or `scripts/coupling`).
"""
