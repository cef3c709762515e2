"""Scenario sweeps: a validated spec expands to runs with stable ids, run by a local or Ray executor.

* :mod:`.spec`      — the sweep-spec YAML schema (:class:`SweepSpec`), override paths checked against the scenario schema;
* :mod:`.expand`    — scenarios x seeds x grid x variants -> :class:`RunTask` list with readable ids;
* :mod:`.worker`    — one run, isolated: metrics + ``run.json`` or ``error.json``;
* :mod:`.executors` — serial / local worker processes / Ray;
* :mod:`.pool`      — the local worker processes: a dead or overdue worker fails only its run;
* :mod:`.faults`    — test-only fault injection (``MONORARP_FAULT``);
* :mod:`.summary`   — ``summary.json`` / ``summary.csv``;
* :mod:`.report`    — the self-contained ``report.html``;
* :mod:`.orchestrate` — orchestration used by ``monorarp sweep``.
"""
