//! The expression language against an outside oracle: random expressions written by
//! `reference/random_expressions.py`, each with its values computed by NumPy from its syntax tree
//! (never from the text), or marked as one to reject. Here each is parsed (with its `[let]` names)
//! and evaluated with `eval` and `eval_many`; the generator has checked the Python reference's
//! parser on the same set. The derivatives `Expr::with_derivatives` compiles are checked against
//! the reference's forward differentiation (first) and its differences (second), where those
//! agree with differences of the values. `EXPR_CASES` and `EXPR_SEED` set the count (10 000) and
//! the seed (1).

use membrane_contact::case::Case;
use membrane_contact::expr::{Expr, ExprError, Names};
use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;

/// Agreement: relative, or both NaN, or the same infinity.
const RTOL: f64 = 1e-12;

fn env_or(key: &str, default: u64) -> u64 {
    std::env::var(key).map_or(default, |v| v.parse().expect("a number"))
}

/// Runs the generator (which also checks reference/expr.py) and reads its cases.
fn generate(seed: u64, count: u64) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cases.json");
    let run = Command::new("/usr/bin/python3")
        .args(["-m", "reference.random_expressions", "--seed", &seed.to_string()])
        .args(["--count", &count.to_string(), "--out"])
        .arg(&out)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run /usr/bin/python3 (`make deps` installs NumPy)");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "the generator failed:\n{stderr}");
    eprint!("{stderr}");
    serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap()
}

fn agree(a: f64, b: f64) -> bool {
    a == b || (a.is_nan() && b.is_nan()) || (a - b).abs() <= RTOL * a.abs().max(b.abs())
}

/// The `[let]` names of a case, each defined with the names after it still to come.
fn names(lets: &[Value]) -> Result<Names, ExprError> {
    let keys: Vec<&str> = lets.iter().map(|kv| kv[0].as_str().unwrap()).collect();
    let mut names = Names::default();
    for (i, kv) in lets.iter().enumerate() {
        names.define(keys[i], kv[1].as_str().unwrap(), &keys[i + 1..])?;
    }
    Ok(names)
}

/// None when the Rust parser agrees with the oracle on `case`, else what differs; `compared`
/// counts the values compared (the oracle leaves out ill-conditioned ones as null).
fn disagreement(case: &Value, points: &[[f64; 2]], compared: &mut usize) -> Option<String> {
    let text = case["text"].as_str().unwrap();
    let parsed = names(case["lets"].as_array().unwrap()).and_then(|n| Expr::parse_with(text, &n));
    let expr = match (parsed, case["reject"].as_str()) {
        (Err(_), Some(_)) => return None,
        (Err(e), None) => return Some(format!("rejected: {e}")),
        (Ok(_), Some(why)) => return Some(format!("accepted, expected a rejection ({why})")),
        (Ok(expr), None) => expr,
    };
    let expected: Vec<Option<f64>> = (case["values"].as_array().unwrap().iter())
        .map(|v| v.as_str().map(|v| v.parse().unwrap()))
        .collect();
    *compared += expected.iter().flatten().count();
    let mut many = vec![0.0; points.len()];
    expr.eval_many(points, &mut many);
    let one: Vec<f64> = points.iter().map(|p| expr.eval(p[0], p[1])).collect();
    let ok = |got: &[f64]| (got.iter().zip(&expected)).all(|(a, b)| b.is_none_or(|b| agree(*a, b)));
    if !ok(&one) || !ok(&many) {
        return Some(format!("eval {one:?}, eval_many {many:?}, expected {expected:?}"));
    }
    derivatives_disagree(&expr, case, points, &many, compared)
}

/// `Expr::with_derivatives` against the generator's derivatives where they are well-conditioned:
/// ∂x, ∂y to 1e-9 and ∂²/∂x², ∂²/∂y² (differences there) to 1e-5 of the size of the value and
/// gradient.
fn derivatives_disagree(
    expr: &Expr,
    case: &Value,
    points: &[[f64; 2]],
    values: &[f64],
    compared: &mut usize,
) -> Option<String> {
    let program = expr.with_derivatives();
    let mut out = [(); 5].map(|_| vec![0.0; points.len()]);
    let [v, dx, dy, dxx, dyy] = &mut out;
    program.eval_many(points, &mut [v, dx, dy, dxx, dyy]);
    let expected = case["derivatives"].as_array()?;
    for (k, d) in expected.iter().enumerate() {
        let Some(d) = d.as_array() else { continue };
        let d: Vec<f64> = d.iter().map(|v| v.as_str().unwrap().parse().unwrap()).collect();
        *compared += 1;
        let got = [out[1][k], out[2][k], out[3][k], out[4][k]];
        let scale = values[k].abs() + d[0].abs() + d[1].abs() + 1.0;
        let tolerance = [
            1e-9 * scale,
            1e-9 * scale,
            1e-5 * (scale + d[2].abs()),
            1e-5 * (scale + d[3].abs()),
        ];
        // Within the tolerance; NaN is not.
        let within = |j: usize| (got[j] - d[j]).abs() <= tolerance[j];
        if !(0..4).all(within) {
            return Some(format!("derivatives at {:?}: {got:?}, expected {d:?}", points[k]));
        }
    }
    None
}

#[test]
fn random_expressions_agree_with_the_oracle() {
    let (seed, count) = (env_or("EXPR_SEED", 1), env_or("EXPR_CASES", 10_000));
    let data = generate(seed, count);
    let points: Vec<[f64; 2]> = (data["points"].as_array().unwrap().iter())
        .map(|p| [0, 1].map(|k| p[k].as_str().unwrap().parse().unwrap()))
        .collect();
    let cases = data["cases"].as_array().unwrap();
    assert!(cases.len() as u64 >= count);
    let mut compared = 0;
    let failures: Vec<String> = (cases.iter())
        .filter_map(|c| {
            disagreement(c, &points, &mut compared)
                .map(|why| format!("{} (lets {}): {why}", c["text"], c["lets"]))
        })
        .collect();
    for f in failures.iter().take(10) {
        eprintln!("{f}");
    }
    assert!(
        failures.is_empty(),
        "{} of {} expressions (seed {seed}) disagree with the oracle at the points {points:?}",
        failures.len(),
        cases.len()
    );
    // Most values are compared: 8 in 10 expressions are valid, and few values ill-conditioned;
    // and the derivatives at most of those points.
    let values = cases.len() * points.len();
    assert!(
        compared * 10 > values * 12,
        "only {compared} of {values} values and as many derivatives compared"
    );
    eprintln!("{} expressions agree; {compared} values compared", cases.len());
}

/// A case with `[let]` names before `f1` (the rest of a valid case after it).
fn case_with_lets(lets: &str) -> Result<Case, String> {
    let text = format!(
        "mu1 = 1.0\nmu2 = 1.0\nf1 = \"r + C\"\nf2 = 0\ng = 0\n[let]\n{lets}\n[mesh]\nkind = \"rectangle\"\nn = 4\n"
    );
    Case::parse(&text, "case.toml", PathBuf::new()).map_err(|e| e.0)
}

#[test]
fn let_table_in_file_order() {
    let case =
        case_with_lets("r = \"sqrt((x-0.5)^2 + (y-0.5)^2)\"\nC = \"sqrt(2)/(sqrt(2)-1) + r - r\"").unwrap();
    let c = 2f64.sqrt() / (2f64.sqrt() - 1.0);
    assert!((case.data.f1.expr().unwrap().eval(0.5, 1.5) - (1.0 + c)).abs() < 1e-15);
    // The same names in the other order: C uses r before it is defined.
    let err = case_with_lets("C = \"sqrt(2)/(sqrt(2)-1) + r - r\"\nr = \"sqrt((x-0.5)^2 + (y-0.5)^2)\"")
        .unwrap_err();
    assert!(
        err.contains("key 'let.C'") && err.contains("'r' is defined later"),
        "{err}"
    );
}

#[test]
fn let_table_errors_name_the_key() {
    let cases = [
        ("r = \"C\"\nC = \"r\"", "key 'let.r'", "'C' is defined later"),
        ("r = \"r + 1\"\nC = 1", "key 'let.r'", "'r' refers to itself"),
        ("r = \"q\"\nC = 1", "key 'let.r'", "unknown name 'q'"),
        ("r = 1\nC = 2\npi = 3", "key 'let.pi'", "shadow a built-in name"),
        ("r = 1\nC = 2\ne = 3", "key 'let.e'", "shadow a built-in name"),
        ("r = 1\nC = 2\nsin = 3", "key 'let.sin'", "shadow a function"),
        ("r = 1\nC = [2]", "key 'let.C'", "need an expression"),
        ("r = 1\nC = \"x < 1\"", "key 'let.C'", "condition"),
        ("r = 1\nC = nan", "key 'let.C' = NaN", "need a finite number"),
    ];
    for (lets, key, message) in cases {
        let err = case_with_lets(lets).unwrap_err();
        assert!(err.contains(key) && err.contains(message), "{lets}: {err}");
    }
    let err = case_with_lets("r = 1").unwrap_err();
    assert!(
        err.contains("key 'f1'") && err.contains("unknown name 'C' (known: x, y, pi, e, r)"),
        "{err}"
    );
}
