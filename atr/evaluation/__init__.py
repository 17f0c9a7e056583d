"""The paper's evaluation (§III): run flights through the pipelines, score (§III-C), pool.

- `runner`: `run_flight(flight, arms, config, templates_3d, templates_2d)` — the services' computations in-process.
- `scoring`: `score_record`, `summarise` — the F1 of eq. (5) with the 2 m translation-error rule.
- `aggregate`: pooled views for the report, and the paper's own numbers.
- `io`: result files keyed by parameters and code version.
- `metrics`: `score_scene`, `count`, `Counts` (the metric itself).
"""
