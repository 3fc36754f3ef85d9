"""The domain library: the model's tables, formulas and constants, held once, for the team models
and the policies alike (a policy never imports a team model or another policy to reuse them).

* `ata.model.tables`: the tables and formulas (image quality, P_rc, t_bar, F_d, fatigue,
  workload, P_hc, working time, utilisation, SA), and the codes of kinds, difficulties, qualities.
* `ata.model.team`: the model's default constants, and the typed constants a team model publishes
  for the policies (`HumanConstants`, `RobotConstants`).
* `ata.model.fatigue`: individual fatigue and the `FatigueBelief` a planner
  projects it with.
* `ata.model.plan`: plans in expectation: where a plan starts from at a decision epoch
  (`plan_start`) and what a fixed allocation is expected to earn from there (`project`).
* `ata.model.load`: the humans' projected load (fatigue, utilisation) while a plan is built step
  by step (`HumanLoad`).
* `ata.model.retask`: the re-tasking cost of docs/model.md (`RetaskCost`, who a change
  re-tasks) and what a candidate allocation is worth net of it (`worth`).
* `ata.model.greedy_score`: greedy's score of a candidate (a human's net value, an option's
  worth, the rate per robot second), written once for the planner and the learned priors.
* `ata.model.greedy_planner`: the greedy list-scheduling planner, the ``greedy`` policy's and
  the prior of the learned methods that build on it.
* `ata.model.generic`: what lets a formula be written once for arrays and numbers (`select`,
  `as_float`); `ata.model.scalar` compiles the formulas so written for the compiled loops.
* `ata.model.events`: the events a policy sees (robots newly down, POIs newly changed), for the
  ``on_event`` condition and the learned conditions alike.

docs/library.md shows how a component uses it.
"""
