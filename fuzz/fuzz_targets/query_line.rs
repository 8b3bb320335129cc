//! Arbitrary text into the query-line parser of `strata eval`: a pair of unit
//! directions or an error, never a panic; errors display without panicking.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(line) = std::str::from_utf8(data) else {
        return;
    };
    match strata_bsdf::query::parse_query_line(line) {
        Ok((wi, wo)) => {
            for d in [wi.get(), wo.get()] {
                let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                assert!(d.iter().all(|x| x.is_finite()), "{d:?}");
                assert!((l - 1.0).abs() < 1e-12, "not unit: {d:?}");
            }
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
});
