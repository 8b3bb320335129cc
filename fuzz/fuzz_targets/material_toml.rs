//! Arbitrary text into the TOML material parser: it returns a stack or an
//! error, never panics; a stack that parses answers queries finitely.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(st) = strata_bsdf::LayerStack::from_toml_str(text) {
        common::exercise(st);
    }
});
