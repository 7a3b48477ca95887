"""The problems a case file can state (its key `problem`) and the names each one uses: case keys,
the vertex fields of a result, the error norms. Every part of the reference that loops over
fields, loads or norms takes them from here, so that one code path serves both problems.

  membranes (the default): two membranes u1 >= u2, tensions mu1, mu2, loads f1, f2, boundary
      values u1 = g, u2 = g2 (default 0); the action lambda of membrane 1 on membrane 2, and
      lambda2 the same action computed from membrane 2's equation.
  obstacle: one membrane u >= psi above a rigid obstacle, tension mu, load f, u = g on the
      boundary; lambda = -mu lap u - f, the obstacle's action.
"""
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Problem:
    name: str
    displacements: tuple  # the unknowns, one per membrane
    tensions: tuple  # the case keys of their tensions, in the same order
    loads: tuple  # the case keys of their loads, in the same order
    actions: tuple  # the written fields of the contact action
    fields: tuple  # every vertex field of a Rust result
    expressions: tuple  # the case keys that hold expressions
    action_signs: tuple  # the sign of lambda_a |D_a| in each membrane's conservation (Lemma 17)
    defaults: dict = field(default_factory=dict)  # optional expression keys and their values

    @property
    def compared(self):
        """The vertex fields compared with a reference (contact is compared as a set)."""
        return self.displacements + ("gap",) + self.actions

    @property
    def exact_keys(self):
        return self.displacements + ("lambda",) + tuple("grad_" + u for u in self.displacements)

    @property
    def fluxes(self):
        """One written flux t_h per membrane (`solve --flux`): (suffix of its names: t1_x, div_t1,
        grad_u1, flux_conservation_1 for "1", t_x, div_t, grad_u, flux_conservation for "";
        case key of its tension; of its load; sign of lambda_a |D_a| in its conservation)."""
        return tuple(zip((u[1:] for u in self.displacements), self.tensions, self.loads, self.action_signs))

    @property
    def error_keys(self):
        """Error norms: the attribute `error_<key>` of a Rust result and of a reference file."""
        return (tuple("l2_" + u for u in self.displacements) + tuple("h1_" + u for u in self.displacements)
                + ("energy", "l2_lambda", "hminus1_lambda"))


MEMBRANES = Problem("membranes", ("u1", "u2"), ("mu1", "mu2"), ("f1", "f2"), ("lambda", "lambda2"),
                    ("u1", "u2", "gap", "lambda", "lambda2", "contact"), ("f1", "f2", "g", "g2"), (1.0, -1.0),
                    {"g2": 0})
OBSTACLE = Problem("obstacle", ("u",), ("mu",), ("f",), ("lambda",), ("u", "psi", "gap", "lambda", "contact"),
                   ("f", "psi", "g"), (1.0,))
PROBLEMS = {p.name: p for p in (MEMBRANES, OBSTACLE)}


def of(case):
    """The Problem a case (a dict from TOML) states."""
    name = case.get("problem", "membranes")
    if name not in PROBLEMS:
        raise ValueError("unknown problem %r (one of %s)" % (name, ", ".join(PROBLEMS)))
    return PROBLEMS[name]


def tensions(case):
    """The case's tensions as floats, in the order of the displacements."""
    return tuple(float(case[k]) for k in of(case).tensions)
