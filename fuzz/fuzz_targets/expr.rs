//! Expressions: parse any text; evaluate what parses at a few points.
#![no_main]
use libfuzzer_sys::fuzz_target;
use membrane_contact::expr::Expr;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(e) = Expr::parse(text) {
            for (x, y) in [(0.0, 0.0), (0.5, -0.25), (-1.0, 1e300), (f64::NAN, 2.0)] {
                let _ = e.eval(x, y);
            }
            let _ = e.constant();
        }
    }
});
