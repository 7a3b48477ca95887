"""The independent Python reference of membrane-contact (dolfinx 0.5 + PETSc), run from the
repository root with Debian's /usr/bin/python3:

    /usr/bin/python3 -m reference.validate --bin target/release/membrane-contact --out validation
    /usr/bin/python3 -m reference.bench_reference --bin target/release/membrane-contact
    /usr/bin/python3 -m reference.bench_table < target/bench.log
    /usr/bin/python3 -m reference.gen_quadrature src/quadrature_tables.rs
    /usr/bin/python3 -m reference.solve_reference RESULT_DIR -o reference.h5
    /usr/bin/python3 -m reference.solve_mixed RESULT_DIR -o mixed.h5
    /usr/bin/python3 -m reference.compare RESULT_DIR reference.h5
    /usr/bin/python3 -m reference.exact_cases [CASE.toml ...]
    /usr/bin/python3 -m reference.ball_check [--sizes 32 64 128]
    /usr/bin/python3 -m reference.paraview_check RESULT_DIR [...]
    /usr/bin/python3 -m reference.estimator --compare RESULT_DIR [...]   (results of solve --estimate)
    /usr/bin/python3 -m reference.random_expressions --seed 1 --count 10000 --out cases.json

Modules:
  problems         the problems a case states (two membranes, obstacle): their keys, fields and norms
  common           result files (Rust results read by `read_result`, reference files), vertex matching
                   by coordinates, lumped masses, case data and expressions
  expr             the case-file expression language, evaluated in NumPy and UFL
  random_expressions  random expressions with values from their syntax trees (tests/expressions.rs)
  solve_reference  SNES-VI in (w = u1 - u2 >= 0, u2), lambda and lambda2 by (4.5), the loads; the
                   obstacle problem in u >= psi_h
  solve_mixed      the mixed (u1, u2, lambda) or (u, lambda) system by primal-dual active sets
  ball_check       the obstacle reference alone on the ball problem: rates against the exact solution
  norms            error norms with the Rust code's rules (L2, H1 on T_h; L2, H-1 on S_h)
  compare          vertex-by-vertex field comparison
  flux_checks      checks of the written flux fields t_1h, t_2h, or t_h above an obstacle (continuity,
                   conservation, rate)
  exact_cases      SymPy check of the exact solutions (SymPy's own parser)
  estimator        the a posteriori estimators of docs/a-posteriori.md (prototype: fluxes dual,
                   dualmin, patch); --compare recomputes the Rust code's `solve --estimate`
  validate         `make validate`
  report           the tables and plots of its report
  paraview_check   ParaView's own XDMF reader on result directories
  bench_reference  `make bench-reference`;  bench_table  the `make bench` table
  gen_quadrature   src/quadrature_tables.rs from basix
"""
