"""The error-against-run-time report of beamstop (GitHub issue 3).

`python -m beamstop_tools.report.generate [--quick]` regenerates report/ (CSV, PNG,
summary.md). Everything here is written from the papers' equations (VSM12, WB00; docs/references.md), not from
beamstop's source: the references and the baselines are independent of the
code under test.
"""
