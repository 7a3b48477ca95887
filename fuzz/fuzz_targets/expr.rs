//! Expressions: parse any text; evaluate what parses at a few points, one by one and as a block,
//! which must agree bit for bit.
#![no_main]
use libfuzzer_sys::fuzz_target;
use membrane_contact::expr::Expr;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(e) = Expr::parse(text) {
            let points = [[0.0, 0.0], [0.5, -0.25], [-1.0, 1e300], [f64::NAN, 2.0]];
            let mut many = [0.0; 4];
            e.eval_many(&points, &mut many);
            for (p, v) in points.iter().zip(many) {
                let one = e.eval(p[0], p[1]);
                assert!(one.to_bits() == v.to_bits() || (one.is_nan() && v.is_nan()));
            }
            let _ = e.constant();
        }
    }
});
