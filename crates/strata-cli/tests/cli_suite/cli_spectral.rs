//! `--wavelengths` on eval, albedo and sample (issue 42): every coloured
//! output has one value per wavelength, each the value a run of its group
//! alone gives (three a walk, or one where the material's IOR varies with
//! wavelength): the passes are assembled in order; bad wavelengths fail
//! naming the flag.

use crate::cli_common::{assert_fails_with, run, scratch, text};

const GOLD: &str =
    "[[layers]]\ninterface = { kind = \"conductor\", preset = \"Au\", roughness = 0.2 }\n";
const DISPERSIVE: &str = "[[layers]]\n\
    interface = { kind = \"dielectric\", ior = { nd = 1.5168, abbe = 30 } }\n\
    medium = { thickness = 1, sigma_t = { nm = [400, 700], values = [2, 0.5] }, albedo = 0.9 }\n\
    [[layers]]\ninterface = { kind = \"diffuse\", albedo = [0.8, 0.5, 0.2] }\n";

/// Writes `toml` to a scratch file for test `name`.
fn material(name: &str, toml: &str) -> String {
    let p = scratch(name).join("m.toml");
    std::fs::write(&p, toml).expect("material");
    p.to_string_lossy().into_owned()
}

/// The JSON line of a successful run.
fn json(args: &[&str], stdin: &str) -> serde_json::Value {
    let out = run(args, stdin);
    assert!(out.status.success(), "{args:?}: {}", text(&out.stderr));
    serde_json::from_str(text(&out.stdout).trim()).expect("one JSON line")
}

fn numbers(v: &serde_json::Value) -> Vec<f64> {
    (v.as_array().expect("an array").iter())
        .map(|x| x.as_f64().expect("a number"))
        .collect()
}

#[test]
fn eval_answers_each_wavelength_as_alone() {
    let m = material("spectral-eval", GOLD);
    let line = "{\"wi\":[0,0,1],\"wo\":[0.3,0.1,0.9]}\n";
    let eval = |nm: &str| {
        let v = json(
            &[
                "eval",
                "--material",
                &m,
                "--samples",
                "8",
                "--wavelengths",
                nm,
            ],
            line,
        );
        (numbers(&v["f"]), numbers(&v["stderr"]))
    };
    let (f, se) = eval("450,550,650,700");
    assert_eq!(f.len(), 4);
    assert_eq!(se, [0.0; 4]);
    assert_eq!(&f[..3], &eval("450,550,650").0[..]);
    assert_eq!(&f[3..], &eval("700").0[..]);
    // Gold reflects red far more than blue.
    assert!(f[0] < 0.6 * f[2], "{f:?}");
    let rgb = json(&["eval", "--material", &m, "--samples", "8"], line);
    assert_eq!(numbers(&rgb["f"]).len(), 3);
}

#[test]
fn albedo_of_a_dispersive_material_takes_a_walk_per_wavelength() {
    let m = material("spectral-albedo", DISPERSIVE);
    let albedo = |nm: &str| {
        let args = [
            "albedo",
            "--material",
            &m,
            "--theta",
            "30",
            "--samples",
            "2000",
        ];
        let v = json(&[&args[..], &["--wavelengths", nm]].concat(), "");
        (numbers(&v["R"]), numbers(&v["stderr_R"]))
    };
    let (r, se) = albedo("450,550,650,700");
    assert_eq!(r.len(), 4);
    for (i, nm) in ["450", "550", "650", "700"].iter().enumerate() {
        assert_eq!(r[i], albedo(nm).0[0], "{nm} nm");
    }
    // Less extinction and a redder base towards 650 nm.
    assert!(r[2] > r[0] + 4.0 * (se[0] + se[2]), "{r:?} ± {se:?}");
}

#[test]
fn sample_weights_have_a_value_per_wavelength() {
    let gold = material("spectral-sample", GOLD);
    let args = [
        "sample",
        "--material",
        &gold,
        "--wi",
        "0,0,1",
        "--count",
        "3",
    ];
    let out = run(&[&args[..], &["--wavelengths", "450,650"]].concat(), "");
    assert!(out.status.success(), "{}", text(&out.stderr));
    for l in text(&out.stdout).lines() {
        let v: serde_json::Value = serde_json::from_str(l).unwrap();
        assert_eq!(numbers(&v["weight"]).len(), 2, "{l}");
    }
    let out = run(
        &[&args[..], &["--wavelengths", "450,550,650,700"]].concat(),
        "",
    );
    assert_fails_with(&out, &["--wavelengths", "at most 3"]);
    let glass = material("spectral-sample-dispersive", DISPERSIVE);
    let args = [
        "sample",
        "--material",
        &glass,
        "--wi",
        "0,0,1",
        "--count",
        "3",
    ];
    let out = run(&[&args[..], &["--wavelengths", "450,550"]].concat(), "");
    assert_fails_with(&out, &["--wavelengths", "at most 1", "IOR varies"]);
}

#[test]
fn bad_wavelengths_fail_naming_the_flag() {
    let m = material("spectral-bad", GOLD);
    for bad in ["450,-3", "450,x", "nan", "450,,550", "0"] {
        let out = run(
            &[
                "albedo",
                "--material",
                &m,
                "--theta",
                "0",
                "--wavelengths",
                bad,
            ],
            "",
        );
        assert_fails_with(&out, &["--wavelengths", "not a positive number of nm"]);
        assert!(out.stdout.is_empty());
    }
}
