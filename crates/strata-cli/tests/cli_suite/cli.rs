//! The command-line tool, run as a user would: the built binary, real files,
//! stdin and stdout. Bad inputs must give a non-zero exit and a message naming
//! the field and value (material files), the line (eval queries) or the flag
//! (arguments); outputs must be valid JSON or PNG; a failed run leaves no file.

use crate::cli_common;
use crate::common;
use cli_common::*;
use common::reference::fresnel;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;
use strata_bsdf::LayerStack;

/// Asserts success and returns stdout.
#[track_caller]
fn assert_ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "strata failed ({}): {}",
        out.status,
        text(&out.stderr)
    );
    text(&out.stdout)
}

fn example_files() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(EXAMPLES)
        .expect("examples/materials")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml" || e == "json"))
        .collect();
    v.sort();
    v
}

fn rgb(v: &Value, key: &str) -> [f64; 3] {
    let a = v[key]
        .as_array()
        .unwrap_or_else(|| panic!("{key} is not an array in {v}"));
    assert_eq!(a.len(), 3, "{key} must have 3 channels: {v}");
    let mut out = [0.0; 3];
    for (o, x) in out.iter_mut().zip(a) {
        *o = x
            .as_f64()
            .unwrap_or_else(|| panic!("{key} has a non-number: {v}"));
        assert!(o.is_finite(), "{key} not finite: {v}");
    }
    out
}

// ------------------------------------------------------------------ examples

#[test]
fn every_example_material_builds_and_says_what_it_models() {
    let files = example_files();
    let names: Vec<String> = files
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    for required in [
        "clear_coat_lambertian.toml",
        "coated_copper.toml",
        "coated_copper.json",
        "varnished_wood.toml",
        "scattering_slab.toml",
        "three_interfaces.toml",
        "validation1.toml",
    ] {
        assert!(names.iter().any(|n| n == required), "missing {required}");
    }
    for p in &files {
        let s = LayerStack::from_path(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        let d = s.desc().description.as_deref().unwrap_or("");
        assert!(d.len() > 20, "{}: no description", p.display());
        if p.extension().is_some_and(|e| e == "toml") {
            let t = std::fs::read_to_string(p).unwrap();
            assert!(t.starts_with("# "), "{}: no header comment", p.display());
        }
    }
    // The JSON file is the same tree as its TOML twin.
    let t = LayerStack::from_path(Path::new(EXAMPLES).join("coated_copper.toml")).unwrap();
    let j = LayerStack::from_path(Path::new(EXAMPLES).join("coated_copper.json")).unwrap();
    assert_eq!(t, j);
    // Validation 1 uses the authors' Mitsuba defaults on both rough interfaces.
    let v = LayerStack::from_path(Path::new(EXAMPLES).join("validation1.toml")).unwrap();
    assert_eq!(v.len(), 2);
    for i in v.interfaces() {
        assert_eq!(i.distribution, strata_bsdf::stack::Distribution::Beckmann);
        assert_eq!(i.shadowing, strata_bsdf::stack::Shadowing::Separable);
        assert_eq!(i.alpha, [0.05, 0.05]);
    }
    let m = v.medium(0).expect("Validation 1 has a medium");
    assert_eq!(
        (m.thickness, m.sigma_t, m.albedo, m.phase.g()),
        (1.0, [1.0; 3], [0.5, 0.7, 0.95], Some(0.5))
    );
    // The 3-interface stack has three interfaces, the slab transmits.
    let three = LayerStack::from_path(Path::new(EXAMPLES).join("three_interfaces.toml")).unwrap();
    assert_eq!(three.len(), 3);
    let slab = LayerStack::from_path(Path::new(EXAMPLES).join("scattering_slab.toml")).unwrap();
    assert!(slab.transmissive());
}

// ------------------------------------------------------------ bad materials

/// Writes `body` to a file in `dir` and runs `albedo` on it.
fn albedo_on(dir: &Path, file: &str, body: &str) -> Output {
    let p = dir.join(file);
    std::fs::write(&p, body).unwrap();
    run(
        &[
            "albedo",
            "--material",
            p.to_str().unwrap(),
            "--theta",
            "30",
            "--samples",
            "10",
        ],
        "",
    )
}

const COAT: &str = r#"interface = { kind = "dielectric", ior = 1.5 }"#;

#[test]
fn bad_material_files_name_the_field_and_value() {
    let dir = scratch("bad-materials");
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        (
            "malformed.toml",
            "[[layers]\ninterface = ".into(),
            vec!["malformed.toml", "TOML", "line 1"],
        ),
        (
            "unknown_field.toml",
            "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, rougness = 0.1 }\n"
                .into(),
            vec!["unknown_field.toml", "rougness", "line 2"],
        ),
        (
            "negative_thickness.toml",
            format!(
                "[[layers]]\n{COAT}\nmedium = {{ thickness = -1.0, sigma_t = 1.0 }}\n\
                 [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n"
            ),
            vec!["layer 0", "medium.thickness = -1", "must be >= 0"],
        ),
        (
            "unknown_preset.toml",
            "[[layers]]\ninterface = { kind = \"conductor\", preset = \"Unobtainium\" }\n".into(),
            vec!["layer 0", "interface.preset", "Unobtainium", "Cu"],
        ),
        (
            "conductor_not_last.toml",
            format!(
                "[[layers]]\ninterface = {{ kind = \"conductor\", preset = \"Au\" }}\n\
                 [[layers]]\n{COAT}\n"
            ),
            vec!["layer 0", "interface.kind", "last"],
        ),
        (
            "nan_thickness.toml",
            format!(
                "[[layers]]\n{COAT}\nmedium = {{ thickness = nan, sigma_t = 1.0 }}\n\
                 [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n"
            ),
            vec!["layer 0", "medium.thickness = NaN", "finite"],
        ),
        (
            "nan_sigma_t.toml",
            format!(
                "[[layers]]\n{COAT}\nmedium = {{ thickness = 1.0, sigma_t = [1.0, nan, 1.0] }}\n\
                 [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n"
            ),
            vec!["layer 0", "medium.sigma_t = [1, NaN, 1]", "finite"],
        ),
        (
            "inf_ior.toml",
            "[[layers]]\ninterface = { kind = \"dielectric\", ior = inf }\n".into(),
            vec!["layer 0", "interface.ior = inf", "finite"],
        ),
        (
            "huge_g.toml",
            format!(
                "[[layers]]\n{COAT}\nmedium = {{ thickness = 1.0, sigma_t = 1.0, \
                 phase = {{ kind = \"hg\", g = 1.0 }} }}\n\
                 [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n"
            ),
            vec!["layer 0", "medium.phase.g = 1", "(-1, 1)"],
        ),
        (
            "albedo_range.toml",
            "[[layers]]\ninterface = { kind = \"diffuse\", albedo = [0.5, 1.5, 0.5] }\n".into(),
            vec!["layer 0", "interface.albedo = [0.5, 1.5, 0.5]", "[0, 1]"],
        ),
        (
            "negative_roughness.toml",
            "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = [0.1, -0.2] }\n"
                .into(),
            vec!["layer 0", "interface.roughness = -0.2"],
        ),
        (
            "empty.toml",
            "layers = []\n".into(),
            vec!["layers", "empty"],
        ),
        (
            "zero_exterior.toml",
            format!("exterior_ior = 0.0\n[[layers]]\n{COAT}\n"),
            vec!["exterior_ior = 0", "> 0"],
        ),
        (
            "malformed.json",
            r#"{"layers": [ {"interface": {"kind": "dielectric", "ior": 1.5} }"#.into(),
            vec!["malformed.json", "JSON", "line 1"],
        ),
        (
            "unknown_kind.json",
            r#"{"layers": [{"interface": {"kind": "plastic", "ior": 1.5}}]}"#.into(),
            vec!["unknown_kind.json", "plastic"],
        ),
    ];
    for (file, body, needles) in &cases {
        let out = albedo_on(&dir, file, body);
        assert_fails_with(&out, needles);
        assert!(
            out.stdout.is_empty(),
            "{file}: printed {}",
            text(&out.stdout)
        );
        assert!(
            text(&out.stderr).contains("--material"),
            "{file}: flag not named"
        );
    }
    // A missing file names the path.
    let missing = dir.join("does_not_exist.toml");
    let out = run(
        &[
            "albedo",
            "--material",
            missing.to_str().unwrap(),
            "--theta",
            "0",
        ],
        "",
    );
    assert_fails_with(&out, &["does_not_exist.toml", "cannot read"]);
    // eval and sample load materials the same way.
    let p = dir.join("negative_thickness.toml");
    let p = p.to_str().unwrap();
    let out = run(&["eval", "--material", p], "");
    assert_fails_with(&out, &["medium.thickness = -1"]);
    let out = run(
        &["sample", "--material", p, "--wi", "0,0,1", "--count", "3"],
        "",
    );
    assert_fails_with(&out, &["medium.thickness = -1"]);
    assert!(out.stdout.is_empty());
}

// ---------------------------------------------------------------------- eval

#[test]
fn eval_answers_each_line_and_names_the_first_bad_one() {
    let m = example("coated_copper.toml");
    let good = r#"{"wi":[0.3,0,0.95],"wo":[-0.3,0.1,0.9]}"#;
    // Valid input: one JSON line per query, with the documented keys.
    let input = format!("{good}\n\n{}\n", r#"{"wi":[0,0,2],"wo":[0,0,1]}"#);
    let out = run(&["eval", "--material", &m, "--samples", "64"], &input);
    let stdout = assert_ok(&out);
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 2, "blank lines are skipped: {stdout}");
    for l in &lines {
        let v: Value = serde_json::from_str(l).expect("valid JSON");
        let f = rgb(&v, "f");
        let e = rgb(&v, "stderr");
        assert!(f.iter().chain(&e).all(|x| *x >= 0.0), "{l}");
        let p = v["pdf"].as_f64().expect("pdf");
        assert!(p.is_finite() && p > 0.0, "{l}");
        assert_eq!(v.as_object().unwrap().len(), 3, "{l}");
    }
    // Bad lines: the message names the line number (blank lines count).
    let bad: [(&str, &[&str]); 7] = [
        (r#"{"wi":[0,0,0],"wo":[0,0,1]}"#, &["wi", "zero length"]),
        (r#"{"wi":[0,0,1],"wo":[0,0,0]}"#, &["wo", "zero length"]),
        (r#"{"wi":[0,0,1],"#, &["invalid query"]),
        (
            r#"{"wi":[0,0],"wo":[0,0,1]}"#,
            &["invalid query", "length 2"],
        ),
        (r#"{"wi":[0,0,1,1],"wo":[0,0,1]}"#, &["invalid query"]),
        (
            r#"{"wi":[0,0,1],"wo":[0,0,1],"x":1}"#,
            &["unknown field", "x"],
        ),
        (r#"{"wi":[0,0,1e400],"wo":[0,0,1]}"#, &["invalid query"]),
    ];
    for (line, needles) in bad {
        let input = format!("{good}\n\n{line}\n{good}\n");
        let out = run(&["eval", "--material", &m, "--samples", "16"], &input);
        let mut all = vec!["stdin line 3"];
        all.extend_from_slice(needles);
        assert_fails_with(&out, &all);
        // The answer to line 1 stands; nothing after the bad line is answered.
        assert_eq!(text(&out.stdout).lines().count(), 1, "{line}");
    }
    // A missing field.
    let out = run(&["eval", "--material", &m], r#"{"wi":[0,0,1]}"#);
    assert_fails_with(&out, &["stdin line 1", "missing field", "wo"]);
    // --samples must be at least 1, named by the flag.
    let out = run(&["eval", "--material", &m, "--samples", "0"], good);
    assert_fails_with(&out, &["--samples", "0"]);
}

// -------------------------------------------------------------------- sample

struct Line {
    wo: Option<[f64; 3]>,
    weight: [f64; 3],
    pdf: Option<f64>,
    reflection: Option<bool>,
    specular: Option<bool>,
}

fn parse_sample_lines(stdout: &str) -> Vec<Line> {
    stdout
        .lines()
        .map(|l| {
            let v: Value = serde_json::from_str(l).unwrap_or_else(|e| panic!("{l}: {e}"));
            assert_eq!(v.as_object().unwrap().len(), 5, "{l}");
            let wo = if v["wo"].is_null() {
                None
            } else {
                Some(rgb(&v, "wo"))
            };
            Line {
                wo,
                weight: rgb(&v, "weight"),
                pdf: v["pdf"].as_f64(),
                reflection: v["reflection"].as_bool(),
                specular: v["specular"].as_bool(),
            }
        })
        .collect()
}

fn sample(m: &str, wi: &str, count: u64, seed: u64) -> Vec<Line> {
    let out = run(
        &[
            "sample",
            "--material",
            m,
            &format!("--wi={wi}"),
            "--count",
            &count.to_string(),
            "--seed",
            &seed.to_string(),
        ],
        "",
    );
    let stdout = assert_ok(&out);
    let lines = parse_sample_lines(&stdout);
    assert_eq!(lines.len() as u64, count);
    lines
}

/// Mean and standard error of per-line values.
fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let v = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0);
    (m, (v / n).sqrt())
}

#[test]
fn sample_prints_valid_lines_with_consistent_flags() {
    // Clear coat (smooth, IOR 1.5) at 60°: the coat's mirror reflection is a
    // delta event; its unbiased weight average is the Fresnel reflectance.
    let m = example("clear_coat_lambertian.toml");
    let t = 60f64.to_radians();
    let wi = [t.sin(), 0.0, t.cos()];
    let n = 20_000;
    let lines = sample(&m, "0.8660254,0,0.5", n, 1);
    let mut spec = Vec::with_capacity(lines.len());
    for l in &lines {
        assert!(l.weight.iter().all(|w| *w >= 0.0), "negative weight");
        match l.wo {
            None => {
                assert_eq!(l.weight, [0.0; 3]);
                assert_eq!((l.reflection, l.specular, l.pdf), (None, None, None));
            }
            Some(wo) => {
                let len = (wo[0] * wo[0] + wo[1] * wo[1] + wo[2] * wo[2]).sqrt();
                assert!((len - 1.0).abs() < 1e-5, "wo not unit: {wo:?}");
                // Opaque stack: every exit is a reflection, above the surface.
                assert_eq!(l.reflection, Some(true));
                assert!(wo[2] > 0.0);
                if l.specular == Some(true) {
                    let mirror = [-wi[0], -wi[1], wi[2]];
                    for k in 0..3 {
                        assert!((wo[k] - mirror[k]).abs() < 1e-5, "{wo:?} vs {mirror:?}");
                    }
                }
            }
        }
        let s = l.specular == Some(true);
        spec.push(if s { l.weight[1] } else { 0.0 });
    }
    let (mean, se) = mean_se(&spec);
    let f = fresnel(t.cos(), 1.0, 1.5);
    assert!(
        (mean - f).abs() <= 5.0 * se + 1e-6,
        "specular albedo {mean} ± {se} vs Fresnel {f}"
    );

    // Same seed, same lines; another seed, other lines.
    let a = run(
        &[
            "sample",
            "--material",
            &m,
            "--wi",
            "0.3,0,1",
            "--count",
            "50",
            "--seed",
            "3",
        ],
        "",
    );
    let b = run(
        &[
            "sample",
            "--material",
            &m,
            "--wi",
            "0.3,0,1",
            "--count",
            "50",
            "--seed",
            "3",
        ],
        "",
    );
    let c = run(
        &[
            "sample",
            "--material",
            &m,
            "--wi",
            "0.3,0,1",
            "--count",
            "50",
            "--seed",
            "4",
        ],
        "",
    );
    assert_eq!(assert_ok(&a), assert_ok(&b));
    assert_ne!(assert_ok(&a), assert_ok(&c));
}

#[test]
fn sample_prints_absorbed_walks_as_null_with_zero_weight() {
    // A thick absorber under a rough coat over silver: most walks die.
    // (Over a Lambertian base `Auto` samples a coat without a walk, and a
    // sample is lost only where the coat's lobe leaves the hemisphere.)
    let dir = scratch("absorbed");
    let p = dir.join("absorber.toml");
    std::fs::write(
        &p,
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.2 }\n\
         medium = { thickness = 5.0, sigma_t = 5.0, albedo = 0.0 }\n\
         [[layers]]\ninterface = { kind = \"conductor\", preset = \"Ag\", roughness = 0.3 }\n",
    )
    .unwrap();
    let lines = sample(p.to_str().unwrap(), "0,0,1", 400, 0);
    let absorbed = lines.iter().filter(|l| l.wo.is_none()).count();
    assert!(absorbed > 100, "only {absorbed} absorbed walks of 400");
    for l in &lines {
        if l.wo.is_none() {
            assert_eq!(l.weight, [0.0; 3]);
            assert_eq!((l.reflection, l.specular, l.pdf), (None, None, None));
        }
    }
}

#[test]
fn sample_lines_carry_the_pdf_eval_reports() {
    // The pdf of a sampled direction is a function of the two directions
    // and the density walks' rule: `strata eval` prints the same number for
    // that pair under the same `--pdf-samples`, and another rule prints
    // another number (the flag reaches both commands).
    for name in ["coated_copper.toml", "scattering_slab.toml"] {
        let m = example(name);
        let wi = "0.5,0,0.8660254";
        let mut pdfs: Vec<Vec<f64>> = Vec::new();
        for rule in [None, Some("tight"), Some("16"), Some("4,32,0.2")] {
            let flags: Vec<&str> = rule.iter().flat_map(|r| ["--pdf-samples", r]).collect();
            let mut args = vec!["sample", "--material", &m, "--count", "64", "--seed", "3"];
            args.push("--wi=0.5,0,0.8660254");
            args.extend(&flags);
            let lines = parse_sample_lines(&assert_ok(&run(&args, "")));
            assert_eq!(lines.len(), 64, "{name} {rule:?}");
            let exited: Vec<&Line> = lines.iter().filter(|l| l.wo.is_some()).collect();
            assert!(exited.len() > 20, "{name}: {} walks left", exited.len());
            let queries: String = exited
                .iter()
                .map(|l| {
                    let wo = l.wo.unwrap();
                    format!(
                        "{{\"wi\":[{wi}],\"wo\":[{},{},{}]}}\n",
                        wo[0] as f32, wo[1] as f32, wo[2] as f32
                    )
                })
                .collect();
            let mut args = vec!["eval", "--material", &m, "--samples", "1", "--seed", "3"];
            args.extend(&flags);
            let out = assert_ok(&run(&args, &queries));
            let mut rule_pdfs = Vec::new();
            for (l, e) in exited.iter().zip(out.lines()) {
                let v: Value = serde_json::from_str(e).unwrap();
                let p = v["pdf"].as_f64().unwrap();
                assert_eq!(
                    l.pdf,
                    Some(p),
                    "{name} {rule:?}: sample {:?} vs eval {e}",
                    l.wo
                );
                assert!(p > 0.0);
                rule_pdfs.push(p);
            }
            pdfs.push(rule_pdfs);
        }
        // The sampled directions are the same under every rule (same seed;
        // only the density walks differ), and each rule's pdf of the first
        // one is its own.
        let first: Vec<f64> = pdfs.iter().map(|p| p[0]).collect();
        for i in 1..first.len() {
            assert_ne!(
                first[0], first[i],
                "{name}: rule {i} gave the default's pdf"
            );
        }
    }
    let m = example("coated_copper.toml");
    for (flag, message) in [
        ("tighter", "expected default, lobes, adaptive, tight"),
        ("0", "0 walks: expected 1 to"),
        ("1,8,0.1", "pilot = 1"),
    ] {
        let bad = run(
            &[
                "sample",
                "--material",
                &m,
                "--wi=0,0,1",
                "--count",
                "1",
                "--pdf-samples",
                flag,
            ],
            "",
        );
        assert!(!bad.status.success(), "{flag}");
        assert!(
            String::from_utf8_lossy(&bad.stderr).contains(message),
            "{flag}"
        );
    }
    let q = "{\"wi\":[0,0,1],\"wo\":[0.6,0,0.8]}\n";
    let bad = run(
        &[
            "eval",
            "--material",
            &m,
            "--pdf",
            "unbiased",
            "--pdf-samples",
            "tight",
        ],
        q,
    );
    assert!(!bad.status.success());
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(
        stderr.contains("--pdf-samples tight: --pdf unbiased takes a number of walks"),
        "{stderr}"
    );
    assert!(bad.stdout.is_empty());
}

#[test]
fn eval_reports_the_unbiased_pdf_with_its_standard_error() {
    // The unbiased pdf (many density walks) and the walked approximate one
    // (its mean over seeds, unmixed) estimate the same density; --pdf
    // unbiased adds pdf_stderr and approx lines do not carry it.
    let m = example("scattering_slab.toml");
    let q = "{\"wi\":[0.5,0,0.8660254],\"wo\":[-0.3,0.1,0.9486833]}\n";
    let unbiased = |seed: &str| {
        let out = assert_ok(&run(
            &[
                "eval",
                "--material",
                &m,
                "--samples",
                "1",
                "--seed",
                seed,
                "--pdf",
                "unbiased",
                "--pdf-samples",
                "20000",
            ],
            q,
        ));
        let v: Value = serde_json::from_str(out.trim()).unwrap();
        (
            v["pdf"].as_f64().unwrap(),
            v["pdf_stderr"].as_f64().unwrap(),
        )
    };
    let (p, se) = unbiased("1");
    assert!(p > 0.0 && se > 0.0 && se < 0.2 * p, "{p} ± {se}");
    let f = strata_bsdf::estimator::pdf::UNIFORM_FRACTION;
    let floor = f / (4.0 * std::f64::consts::PI);
    let approx: Vec<f64> = (0..64)
        .map(|s| {
            let out = assert_ok(&run(
                &[
                    "eval",
                    "--material",
                    &m,
                    "--samples",
                    "1",
                    "--seed",
                    &s.to_string(),
                    "--pdf-samples",
                    "adaptive",
                ],
                q,
            ));
            let v: Value = serde_json::from_str(out.trim()).unwrap();
            assert!(v.get("pdf_stderr").is_none(), "{out}");
            (v["pdf"].as_f64().unwrap() - floor) / (1.0 - f)
        })
        .collect();
    let (mean, mean_se) = mean_se(&approx);
    let combined = (se * se + mean_se * mean_se).sqrt();
    assert!(
        (mean - p).abs() <= 4.0 * combined,
        "approx {mean} ± {mean_se} vs unbiased {p} ± {se}"
    );
    let bad = run(&["eval", "--material", &m, "--pdf", "exact"], q);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("approx or unbiased"));
}

#[test]
fn importance_transport_is_the_adjoint_across_different_exteriors() {
    // Glass below, air above: importance eval is radiance eval times
    // (n_i / n_o)^2 for transmission, and the same for reflection.
    let dir = scratch("transport");
    let p = dir.join("glass.toml");
    std::fs::write(
        &p,
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.3 }\n",
    )
    .unwrap();
    let m = p.to_str().unwrap();
    let q = "{\"wi\":[0.5,0,0.8660254],\"wo\":[-0.3,0.1,-0.9486833]}\n\
             {\"wi\":[0.3,0,-0.9539392],\"wo\":[-0.5,0,0.8660254]}\n\
             {\"wi\":[0.5,0,0.8660254],\"wo\":[-0.4,0,0.9165151]}\n";
    let eval = |mode: &str| -> Vec<f64> {
        let out = assert_ok(&run(&["eval", "--material", m, "--transport", mode], q));
        out.lines()
            .map(|l| rgb(&serde_json::from_str(l).unwrap(), "f")[0])
            .collect()
    };
    let (r, i) = (eval("radiance"), eval("importance"));
    for (k, s) in [1.0 / 2.25, 2.25, 1.0].into_iter().enumerate() {
        assert!(r[k] > 0.0);
        assert!(
            (i[k] - r[k] * s).abs() <= 1e-12 * i[k],
            "line {k}: {} vs {} x {s}",
            i[k],
            r[k]
        );
    }
    let out = run(&["eval", "--material", m, "--transport", "light"], q);
    assert_fails_with(&out, &["--transport", "light"]);
}

#[test]
fn sample_mean_weight_matches_albedo() {
    // Transmissive slab: mean weights of reflected and transmitted lines are
    // the albedos R and T; compared with `strata albedo` on another seed.
    let m = example("scattering_slab.toml");
    let n = 20_000;
    let lines = sample(&m, "0.5,0,0.8660254", n, 11);
    let split = |refl: bool| -> Vec<f64> {
        lines
            .iter()
            .map(|l| {
                if l.reflection == Some(refl) {
                    l.weight[0]
                } else {
                    0.0
                }
            })
            .collect()
    };
    let (r, se_r) = mean_se(&split(true));
    let (t, se_t) = mean_se(&split(false));
    let out = run(
        &[
            "albedo",
            "--material",
            &m,
            "--theta",
            "30",
            "--samples",
            "20000",
            "--seed",
            "12",
        ],
        "",
    );
    let v: Value = serde_json::from_str(assert_ok(&out).trim()).unwrap();
    let (ar, at) = (rgb(&v, "R")[0], rgb(&v, "T")[0]);
    let (ser, set) = (rgb(&v, "stderr_R")[0], rgb(&v, "stderr_T")[0]);
    let zr = (r - ar).abs() / (se_r * se_r + ser * ser).sqrt();
    let zt = (t - at).abs() / (se_t * se_t + set * set).sqrt();
    assert!(zr < 5.0, "R: sample {r} ± {se_r}, albedo {ar} ± {ser}");
    assert!(zt < 5.0, "T: sample {t} ± {se_t}, albedo {at} ± {set}");
    assert!(t > 0.2 && r > 0.05, "the slab both reflects and transmits");
}

#[test]
fn sample_rejects_bad_directions_naming_the_flag() {
    let m = example("clear_coat_lambertian.toml");
    for (wi, needle) in [
        ("0,0,0", "zero length"),
        ("1,2", "three numbers"),
        ("a,0,1", "\"a\" is not a number"),
        ("1e99,0,1", "not a finite number"),
    ] {
        let out = run(
            &[
                "sample",
                "--material",
                &m,
                &format!("--wi={wi}"),
                "--count",
                "5",
            ],
            "",
        );
        assert_fails_with(&out, &["--wi", wi, needle]);
        assert!(out.stdout.is_empty());
    }
    let out = run(&["sample", "--material", &m, "--wi", "0,0,1"], "");
    assert_fails_with(&out, &["--count"]);
}

// -------------------------------------------------------------------- albedo

#[test]
fn albedo_is_valid_json_and_conserves_energy_on_every_example() {
    for p in example_files() {
        for theta in ["0", "70"] {
            let out = run(
                &[
                    "albedo",
                    "--material",
                    p.to_str().unwrap(),
                    "--theta",
                    theta,
                    "--samples",
                    "4000",
                ],
                "",
            );
            let s = assert_ok(&out);
            assert_eq!(s.lines().count(), 1);
            let v: Value = serde_json::from_str(s.trim()).expect("valid JSON");
            assert_eq!(v.as_object().unwrap().len(), 4, "{s}");
            let (r, t) = (rgb(&v, "R"), rgb(&v, "T"));
            let (er, et) = (rgb(&v, "stderr_R"), rgb(&v, "stderr_T"));
            for c in 0..3 {
                assert!(r[c] >= 0.0 && t[c] >= 0.0, "{}: {s}", p.display());
                let se = (er[c] * er[c] + et[c] * et[c]).sqrt();
                assert!(
                    r[c] + t[c] <= 1.0 + 5.0 * se,
                    "{} at {theta}°: R + T = {} ± {se}",
                    p.display(),
                    r[c] + t[c]
                );
            }
        }
    }
    // A lossless stack (smooth coat over a white base) reflects everything.
    let dir = scratch("lossless");
    let p = dir.join("white.toml");
    std::fs::write(
        &p,
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 1.0 }\n",
    )
    .unwrap();
    let out = run(
        &[
            "albedo",
            "--material",
            p.to_str().unwrap(),
            "--theta",
            "45",
            "--samples",
            "20000",
        ],
        "",
    );
    let v: Value = serde_json::from_str(assert_ok(&out).trim()).unwrap();
    let (r, e) = (rgb(&v, "R"), rgb(&v, "stderr_R"));
    for c in 0..3 {
        assert!(
            (r[c] - 1.0).abs() <= 5.0 * e[c] + 1e-5,
            "R = {} ± {}",
            r[c],
            e[c]
        );
    }
}

#[test]
fn albedo_rejects_bad_flags_naming_them() {
    let m = example("clear_coat_lambertian.toml");
    let out = run(&["albedo", "--material", &m, "--theta", "200"], "");
    assert_fails_with(&out, &["--theta 200", "[0, 180]"]);
    let out = run(&["albedo", "--material", &m, "--theta", "-5"], "");
    assert_fails_with(&out, &["--theta -5"]);
    let out = run(&["albedo", "--material", &m, "--theta", "nan"], "");
    assert_fails_with(&out, &["--theta NaN"]);
    let out = run(
        &["albedo", "--material", &m, "--theta", "10", "--phi", "inf"],
        "",
    );
    assert_fails_with(&out, &["--phi inf"]);
    let out = run(
        &[
            "albedo",
            "--material",
            &m,
            "--theta",
            "10",
            "--samples",
            "0",
        ],
        "",
    );
    assert_fails_with(&out, &["--samples", "0"]);
    let out = run(&["albedo", "--material", &m, "--theta", "ten"], "");
    assert_fails_with(&out, &["--theta", "ten"]);
}

// ---------------------------------------------------------------------- demo

/// Decodes a PNG and returns (width, height, RGB pixels).
fn decode_png(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let dec = png::Decoder::new(bytes);
    let mut reader = dec.read_info().expect("PNG header");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("PNG data");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

#[test]
fn demo_writes_readable_pngs_and_tables() {
    let dir = scratch("demo");
    let out_dir = dir.join("figures");
    let out = run(
        &["demo", "--out", out_dir.to_str().unwrap(), "--samples", "8"],
        "",
    );
    let stdout = assert_ok(&out);
    for needle in ["Directional albedo", "BSDF values", "validation1", "±"] {
        assert!(stdout.contains(needle), "table lacks {needle:?}: {stdout}");
    }
    let figures = names(&out_dir);
    assert_eq!(
        figures,
        [
            "clear_coat_lambertian.png",
            "coated_copper.png",
            "scattering_slab.png",
            "validation1.png",
            "varnished_wood.png"
        ],
        "only the figures, no temporary files"
    );
    for n in &figures {
        let bytes = std::fs::read(out_dir.join(n)).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{n}: not a PNG");
        let (w, h, px) = decode_png(&bytes);
        assert!(w >= 800 && h >= 400, "{n}: {w}x{h}");
        // The curves are drawn: pixels of the first two palette colours.
        let count = |c: [u8; 3]| px.chunks_exact(3).filter(|p| *p == c).count();
        assert!(count([0, 114, 178]) > 500, "{n}: first lobe missing");
        assert!(count([213, 94, 0]) > 500, "{n}: second lobe missing");
        // And text: a good share of dark pixels, but mostly white background.
        let dark = px
            .chunks_exact(3)
            .filter(|p| p.iter().all(|&x| x < 80))
            .count();
        let white = px
            .chunks_exact(3)
            .filter(|p| p.iter().all(|&x| x == 255))
            .count();
        assert!(dark > 2000, "{n}: no text or axes ({dark} dark pixels)");
        assert!(white > px.len() / 3 / 2, "{n}: not a white background");
    }
}

#[test]
fn demo_with_an_impossible_output_path_fails_and_leaves_nothing() {
    let dir = scratch("demo-bad-out");
    let blocker = dir.join("blocker");
    std::fs::write(&blocker, b"a file, not a directory").unwrap();
    let target = blocker.join("figures");
    let out = run(
        &["demo", "--out", target.to_str().unwrap(), "--samples", "4"],
        "",
    );
    assert_fails_with(&out, &["--out", "blocker", "cannot create"]);
    assert!(out.stdout.is_empty(), "{}", text(&out.stdout));
    assert_eq!(names(&dir), ["blocker"], "only the blocker remains");
    assert_eq!(std::fs::read(&blocker).unwrap(), b"a file, not a directory");

    // A figure that cannot be written (a directory stands in its place) fails
    // before the work (no table printed), with no temporary or partial file
    // left behind.
    let out_dir = dir.join("figures");
    std::fs::create_dir_all(out_dir.join("clear_coat_lambertian.png")).unwrap();
    let out = run(
        &["demo", "--out", out_dir.to_str().unwrap(), "--samples", "4"],
        "",
    );
    assert_fails_with(&out, &["--out", "clear_coat_lambertian.png"]);
    assert!(out.stdout.is_empty(), "{}", text(&out.stdout));
    assert_eq!(
        names(&out_dir),
        ["clear_coat_lambertian.png"],
        "left behind"
    );
    assert!(out_dir.join("clear_coat_lambertian.png").is_dir());
}

#[test]
fn example_materials_round_trip_through_toml_and_json() {
    // The description a stack keeps can be written out and read back.
    for p in example_files() {
        let s = LayerStack::from_path(&p).unwrap();
        let t = toml::to_string(s.desc()).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert_eq!(LayerStack::from_toml_str(&t).unwrap(), s, "{t}");
        let j = serde_json::to_string(s.desc()).unwrap();
        assert_eq!(LayerStack::from_json_str(&j).unwrap(), s, "{j}");
    }
    // Integers are numbers, and one number is an RGB grey.
    let a = LayerStack::from_toml_str(
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 2 }\n\
         medium = { thickness = 1, sigma_t = 3, albedo = [1, 0.5, 0] }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 1 }\n",
    )
    .unwrap();
    let m = a.medium(0).unwrap();
    assert_eq!(
        (m.thickness, m.sigma_t, m.albedo),
        (1.0, [3.0; 3], [1.0, 0.5, 0.0])
    );
    assert_eq!(a.interface(0).n_below, 2.0);
    assert_eq!(a.interface(1).albedo, [1.0; 3]);
}

#[test]
fn engines_and_thread_counts_print_the_same_answers() {
    let m = example("varnished_wood.toml");
    let queries = "{\"wi\":[0,0,1],\"wo\":[0.3,0,1]}\n{\"wi\":[0.5,0.1,1],\"wo\":[-0.3,0.2,1]}\n";
    let base = ["eval", "--material", &m, "--samples", "700"];
    let reference = assert_ok(&run(
        &[&base[..], &["--engine", "scalar"]].concat(),
        queries,
    ));
    for extra in [
        &["--engine", "wavefront"][..],
        &["--engine", "auto"],
        &["--threads", "1"],
        &["--threads", "3"],
    ] {
        let out = assert_ok(&run(&[&base[..], extra].concat(), queries));
        assert_eq!(out, reference, "eval {extra:?}");
    }
    let m = example("scattering_slab.toml");
    let albedo = |extra: &[&str]| albedo_at_40(&m, "3000", extra);
    assert_eq!(
        albedo(&["--engine", "scalar"]),
        albedo(&["--threads", "2"]),
        "albedo"
    );
    let sample = |extra: &[&str]| {
        let args = [
            &[
                "sample",
                "--material",
                &m,
                "--wi",
                "0.2,0,1",
                "--count",
                "300",
            ][..],
            extra,
        ]
        .concat();
        assert_ok(&run(&args, ""))
    };
    assert_eq!(sample(&["--engine", "scalar"]), sample(&[]), "sample");
    assert_eq!(sample(&["--engine", "auto"]), sample(&[]), "sample, auto");
    assert_fails_with(
        &run(&[&base[..], &["--engine", "gpu"]].concat(), queries),
        &["--engine", "gpu"],
    );
    assert_fails_with(
        &run(&[&base[..], &["--threads", "0"]].concat(), queries),
        &["--threads", "0"],
    );
}

/// The command-line examples in docs/guide.md print what the binary prints
/// (so the guide cannot go stale): each `$ ...` line of its example block is run
/// (an `echo '...' |` prefix becomes stdin) and its output compared line by line.
#[test]
fn readme_examples_match_the_binary() {
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/guide.md"))
            .expect("docs/guide.md");
    let start = readme
        .find("```sh\n$ echo")
        .expect("the guide's example block");
    let block = &readme[start + 6..];
    let block = &block[..block.find("```").expect("end of block")];
    let mut runs: Vec<(String, Vec<String>)> = Vec::new();
    for line in block.lines() {
        if let Some(cmd) = line.strip_prefix("$ ") {
            runs.push((cmd.to_string(), Vec::new()));
        } else if let Some(last) = runs.last_mut() {
            last.1.push(line.to_string());
        }
    }
    assert!(runs.len() >= 3, "guide examples found: {}", runs.len());
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    for (cmd, expected) in runs {
        let (stdin, cmd) = match cmd.split_once(" | ") {
            Some((echo, rest)) => {
                let text = echo.trim_start_matches("echo ").trim_matches('\'');
                (format!("{text}\n"), rest.to_string())
            }
            None => (String::new(), cmd),
        };
        let args: Vec<String> = cmd
            .split_whitespace()
            .skip(1) // "strata"
            .map(|a| a.replace("examples/", &format!("{root}/examples/")))
            .collect();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = assert_ok(&run(&args, &stdin));
        let got: Vec<&str> = out.lines().collect();
        assert_eq!(got, expected, "guide example `{cmd}`");
    }
}

#[test]
fn bench_reports_every_engine_as_json_and_one_with_only() {
    let mat = format!("{EXAMPLES}/coated_copper.toml");
    let base = [
        "bench",
        "--json",
        "--queries",
        "3",
        "--samples",
        "16",
        "--min-seconds",
        "0",
        "--threads",
        "2",
        "--material",
        &mat,
    ];
    let rows = |out: &Output| -> Vec<Value> {
        assert!(out.status.success(), "stderr: {}", text(&out.stderr));
        text(&out.stdout)
            .lines()
            .map(|l| serde_json::from_str(l).expect("a JSON object per line"))
            .collect()
    };
    let engines = |rows: &[Value]| -> Vec<(String, u64)> {
        rows.iter()
            .map(|r| {
                (
                    r["engine"].as_str().unwrap().to_string(),
                    r["threads"].as_u64().unwrap(),
                )
            })
            .collect()
    };
    let all = rows(&run(&[&base[..], &["--bidir"]].concat(), ""));
    let expect = [
        ("scalar", 1),
        ("wavefront", 1),
        ("wavefront-varying", 1),
        ("wavefront", 2),
        ("wavefront-varying", 2),
        ("wavefront-general", 1),
        ("wavefront-f32x16", 1),
        ("scalar-bidir", 1),
        ("wavefront-bidir", 1),
    ];
    let expect = expect.map(|(e, t)| (e.to_string(), t)).to_vec();
    assert_eq!(engines(&all), expect);
    // Without --bidir, the same rows but the bidirectional ones.
    let default = rows(&run(&base, ""));
    let uni: Vec<(String, u64)> = (expect.iter())
        .filter(|(e, _)| !e.ends_with("-bidir"))
        .cloned()
        .collect();
    assert_eq!(engines(&default), uni);
    for r in &all {
        let q = r["queries_per_s"].as_f64().unwrap();
        assert!(q.is_finite() && q > 0.0, "{r}");
        let bidir = r["engine"].as_str().unwrap().ends_with("-bidir");
        // The bidirectional walks' segments are not counted.
        match r["segments_per_s"].as_f64() {
            Some(s) => assert!(!bidir && s.is_finite() && s > q, "{r}"),
            None => assert!(bidir, "{r}"),
        }
        match r["occupancy"].as_f64() {
            Some(o) => assert!(o > 0.0 && o <= 1.0, "{r}"),
            None => assert!(r["engine"] == "scalar" || bidir, "{r}"),
        }
    }
    let only = rows(&run(&[&base[..], &["--only", "wavefront"]].concat(), ""));
    assert_eq!(only.len(), 1);
    assert_eq!(
        (&only[0]["engine"], &only[0]["threads"]),
        (&Value::from("wavefront"), &Value::from(1))
    );
    assert_fails_with(
        &run(&[&base[..], &["--only", "gpu"]].concat(), ""),
        &["--only", "gpu"],
    );
    // One interface: no bidirectional walks, said rather than no rows.
    let one = scratch("bench-one-interface").join("one_interface.toml");
    std::fs::write(
        &one,
        "[[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.5 }\n",
    )
    .unwrap();
    let one = one.to_str().unwrap();
    let mut args = base.to_vec();
    let at = args.iter().position(|a| *a == mat.as_str()).unwrap();
    args[at] = one;
    let out = run(&[&args[..], &["--only", "wavefront-bidir"]].concat(), "");
    assert_fails_with(&out, &["--only", "wavefront-bidir", "one interface"]);
}

#[test]
fn eval_estimator_and_start_flags_choose_how_eval_estimates() {
    // A clear coat over Lambertian has a closed form: exact (stderr 0) by
    // default, walks with --estimator uni or bidir; a grazing-light pair
    // runs other walks with --eval-start wi; all agree within their errors.
    let m = example("clear_coat_lambertian.toml");
    let q = "{\"wi\":[0.9848077,0,0.17364818],\"wo\":[0,0,1]}\n";
    let f = |extra: &[&str]| -> ([f64; 3], [f64; 3]) {
        let mut args = vec!["eval", "--material", m.as_str(), "--samples", "20000"];
        args.extend_from_slice(extra);
        let out = assert_ok(&run(&args, q));
        let v: Value = serde_json::from_str(out.trim()).unwrap();
        (rgb(&v, "f"), rgb(&v, "stderr"))
    };
    let (exact, se0) = f(&[]);
    assert_eq!(se0, [0.0; 3]);
    let (walks, se) = f(&["--estimator", "uni"]);
    let (from_wi, se_wi) = f(&["--estimator", "uni", "--eval-start", "wi"]);
    assert_ne!(walks, from_wi, "--eval-start wi ran the same walks");
    for c in 0..3 {
        assert!(se[c] > 0.0 && se_wi[c] > 0.0);
        assert!((walks[c] - exact[c]).abs() <= 4.0 * se[c] + 1e-6 * exact[c]);
        assert!((from_wi[c] - exact[c]).abs() <= 4.0 * se_wi[c] + 1e-6 * exact[c]);
    }
    // The bidirectional walks agree with the closed form too.
    let (bidir, se_b) = f(&["--estimator", "bidir"]);
    for c in 0..3 {
        assert!(se_b[c] > 0.0);
        assert!((bidir[c] - exact[c]).abs() <= 4.0 * se_b[c] + 1e-6 * exact[c]);
    }
    assert_fails_with(
        &run(&["eval", "--material", &m, "--estimator", "both"], q),
        &["--estimator", "both"],
    );
    assert_fails_with(
        &run(&["eval", "--material", &m, "--eval-start", "wo"], q),
        &["--eval-start", "wo"],
    );
}

#[test]
fn bench_against_pbrt_v4_reports_every_pair() {
    let out = run(
        &[
            "bench",
            "--against",
            "pbrt-v4",
            "--walks",
            "64",
            "--reps",
            "1",
            "--threads",
            "1",
            "--json",
        ],
        "",
    );
    let lines: Vec<Value> = assert_ok(&out)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // 6 configurations x 21 pairs, one thread.
    assert_eq!(lines.len(), 126);
    for l in &lines {
        assert!(l["f"].as_f64().unwrap() >= 0.0 && l["pbrt_f"].as_f64().unwrap() > 0.0);
        let exact = l["exact"].as_bool().unwrap();
        assert_eq!(exact, l["config"] == "coated_diffuse_smooth_alb0", "{l}");
        if exact {
            assert_eq!(l["efficiency_ratio"], "exact");
        } else if l["se"].as_f64().unwrap() > 0.0 {
            assert!(l["efficiency_ratio"].as_f64().unwrap() > 0.0, "{l}");
        } else {
            // 64 walks that all scored 0 beyond the exact first-order term:
            // no variance measured, no ratio.
            assert!(l["efficiency_ratio"].is_null(), "{l}");
        }
    }
    let table = assert_ok(&run(
        &[
            "bench",
            "--against",
            "pbrt-v4",
            "--walks",
            "64",
            "--reps",
            "1",
            "--threads",
            "1",
        ],
        "",
    ));
    assert!(
        table.contains("timing_amd_epyc_2026-12-01.csv")
            && table.contains("coated_conductor_rough_cu_rough0.1")
    );
    assert_fails_with(
        &run(&["bench", "--against", "mitsuba"], ""),
        &["--against", "mitsuba"],
    );
}

// ---------------------------------------------------------------- set

/// A line's `"set"` answers what a material file with those values answers,
/// bit for bit (lines with and without sets mixed in one run, and sets that
/// change the stack's shape); `strata sample --set` draws what the file's
/// walks draw; a set that names nothing, or makes a value invalid, stops the
/// run naming the line, the path and the value.
#[test]
fn eval_lines_and_sample_set_values_of_their_own() {
    let dir = scratch("set");
    let base = "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.2 }\n\
                medium = { thickness = 0.5, sigma_t = [0.5, 1.0, 2.0], albedo = 0.8 }\n\
                [[layers]]\ninterface = { kind = \"conductor\", preset = \"Cu\", roughness = 0.3 }\n";
    // The same material with the set's values written in (the preset's eta
    // and k replaced by explicit values), and one whose roughness 0 makes
    // the coat smooth (another shape).
    let set_a = r#"{"layers[0].medium.thickness":1.25,"layers[1].interface.eta":[0.3,0.5,1.2],"layers[1].interface.k":[3,2.5,2]}"#;
    let file_a = "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.2 }\n\
                  medium = { thickness = 1.25, sigma_t = [0.5, 1.0, 2.0], albedo = 0.8 }\n\
                  [[layers]]\ninterface = { kind = \"conductor\", eta = [0.3, 0.5, 1.2], k = [3, 2.5, 2], roughness = 0.3 }\n";
    let set_b = r#"{"layers[0].interface.roughness":0,"layers[0].interface.ior":1.33}"#;
    let file_b = "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.33, roughness = 0 }\n\
                  medium = { thickness = 0.5, sigma_t = [0.5, 1.0, 2.0], albedo = 0.8 }\n\
                  [[layers]]\ninterface = { kind = \"conductor\", preset = \"Cu\", roughness = 0.3 }\n";
    let write = |name: &str, body: &str| {
        let p = dir.join(name);
        std::fs::write(&p, body).unwrap();
        p.display().to_string()
    };
    let (m0, ma, mb) = (
        write("base.toml", base),
        write("a.toml", file_a),
        write("b.toml", file_b),
    );
    let dirs = [
        r#""wi":[0.3,0,0.95],"wo":[-0.3,0.1,0.9]"#,
        r#""wi":[0.8,0,0.6],"wo":[0,0.6,0.8]"#,
        r#""wi":[0,0.1,1],"wo":[0.9,0,0.3]"#,
    ];
    let mut input = String::new();
    let mut expect: Vec<(&str, usize)> = Vec::new();
    for (k, d) in dirs.iter().enumerate() {
        input += &format!("{{{d}}}\n{{{d},\"set\":{set_a}}}\n{{{d},\"set\":{set_b}}}\n");
        expect.extend([(m0.as_str(), k), (ma.as_str(), k), (mb.as_str(), k)]);
    }
    let flags = ["--samples", "64", "--seed", "3"];
    let eval = |m: &str, input: &str| {
        let mut a = vec!["eval", "--material", m];
        a.extend(flags);
        assert_ok(&run(&a, input))
    };
    let got = eval(&m0, &input);
    let got: Vec<&str> = got.lines().collect();
    assert_eq!(got.len(), 9);
    for (line, (m, k)) in got.iter().zip(&expect) {
        let want = eval(m, &format!("{{{}}}\n", dirs[*k]));
        assert_eq!(*line, want.trim_end(), "{m} query {k}");
    }
    // The sets change the answers (else the above could pass with them ignored).
    assert_ne!(got[0], got[1]);
    assert_ne!(got[0], got[2]);
    // strata sample --set.
    let sample = |m: &str, set: Option<&str>| {
        let mut a = vec![
            "sample",
            "--material",
            m,
            "--wi",
            "0.3,0,0.95",
            "--count",
            "50",
        ];
        if let Some(s) = set {
            a.extend(["--set", s]);
        }
        assert_ok(&run(&a, ""))
    };
    assert_eq!(sample(&m0, Some(set_a)), sample(&ma, None));
    assert_ne!(sample(&m0, Some(set_a)), sample(&m0, None));
    // Bad sets stop the run at their line, naming the path and the value.
    let good = format!("{{{}}}\n", dirs[0]);
    let bad: [(&str, &[&str]); 4] = [
        (
            r#"{"layers[0].medium.thickness":-1}"#,
            &["stdin line 2", "layers[0].medium.thickness", "-1"],
        ),
        (
            r#"{"layers[5].medium.thickness":1}"#,
            &["stdin line 2", "layers[5]"],
        ),
        (
            r#"{"layers[0].interface.albedo":0.5}"#,
            &["stdin line 2", "layers[0].interface.albedo"],
        ),
        (
            r#"{"layers[0].medium.thickness":"thick"}"#,
            &["stdin line 2", "thick"],
        ),
    ];
    for (set, needles) in bad {
        let input = format!("{good}{{{},\"set\":{set}}}\n{good}", dirs[1]);
        let out = run(&["eval", "--material", &m0, "--samples", "8"], &input);
        assert_fails_with(&out, needles);
        assert_eq!(text(&out.stdout).lines().count(), 1, "{set}");
    }
    let out = run(
        &[
            "sample",
            "--material",
            &m0,
            "--wi",
            "0,0,1",
            "--count",
            "1",
            "--set",
            "{\"x\":1}",
        ],
        "",
    );
    assert_fails_with(&out, &["--set", "x"]);
}

/// `strata albedo` of `material` at θ 40° with `samples` walks and the
/// flags `extra`: its JSON line.
fn albedo_at_40(material: &str, samples: &str, extra: &[&str]) -> String {
    let args = [
        &[
            "albedo",
            "--material",
            material,
            "--theta",
            "40",
            "--samples",
            samples,
        ][..],
        extra,
    ]
    .concat();
    assert_ok(&run(&args, ""))
}

/// `--max-events` is the library's limit of events per walk: at 3 events a
/// scattering slab reflects less than under the default, whose answers are
/// those of `--max-events 1048576`; a limit outside 1..=2^24 fails naming it.
#[test]
fn max_events_limits_the_walks() {
    let m = example("scattering_slab.toml");
    let albedo = |extra: &[&str]| albedo_at_40(&m, "20000", extra);
    let full = albedo(&[]);
    assert_eq!(full, albedo(&["--max-events", "1048576"]));
    let three = albedo(&["--max-events", "3"]);
    let reflected = |out: &str| -> (f64, f64) {
        let v: Value = serde_json::from_str(out.lines().next().unwrap()).unwrap();
        (
            v["R"][0].as_f64().unwrap(),
            v["stderr_R"][0].as_f64().unwrap(),
        )
    };
    let ((a, sa), (b, sb)) = (reflected(&full), reflected(&three));
    assert!((a - b) / sa.hypot(sb) > 5.0, "{three}\n{full}");
    for bad in ["0", "16777217", "x"] {
        let args = ["albedo", "--material", &m, "--max-events", bad];
        assert_fails_with(&run(&args, ""), &["--max-events", bad]);
    }
}

/// `--config` takes the library's configuration text and is applied after
/// the other flags: each setting prints what its flag prints, bit for bit,
/// in `eval`, `sample` and `albedo`; it overrides a flag; a setting the
/// library does not take fails with the library's message, naming the key
/// and the value.
#[test]
fn config_sets_what_the_flags_set() {
    let p = scratch("config").join("glass.toml");
    std::fs::write(
        &p,
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.3 }\n",
    )
    .unwrap();
    let m = p.to_str().unwrap();
    let q = "{\"wi\":[0.5,0,0.8660254],\"wo\":[-0.3,0.1,-0.9486833]}\n\
             {\"wi\":[0.3,0,-0.9539392],\"wo\":[-0.5,0,0.8660254]}\n";
    let slab = example("scattering_slab.toml");
    let eval = |material: &str, extra: &[&str]| {
        let args = [&["eval", "--material", material][..], extra].concat();
        assert_ok(&run(&args, q))
    };
    for (material, flags, config) in [
        (
            m,
            &["--transport", "importance"][..],
            "transport=importance",
        ),
        (
            &slab,
            &["--samples", "64", "--seed", "3", "--estimator", "bidir"],
            "samples=64 seed=3 estimator=bidir",
        ),
        (
            &slab,
            &[
                "--eval-start",
                "wi",
                "--max-events",
                "4",
                "--pdf-samples",
                "4",
            ],
            "eval_start=wi max_events=4 pdf_walks=4",
        ),
    ] {
        let by_flags = eval(material, flags);
        assert_ne!(
            by_flags,
            eval(material, &[]),
            "{flags:?} changes the answers"
        );
        assert_eq!(eval(material, &["--config", config]), by_flags, "{config}");
    }
    assert_eq!(
        eval(
            m,
            &[
                "--transport",
                "importance",
                "--config",
                "transport=radiance"
            ]
        ),
        eval(m, &[]),
        "--config overrides the flag"
    );
    let sample = |extra: &[&str]| {
        let args = [
            &[
                "sample",
                "--material",
                m,
                "--wi",
                "0.3,0,0.9",
                "--count",
                "40",
            ][..],
            extra,
        ]
        .concat();
        assert_ok(&run(&args, ""))
    };
    assert_eq!(
        sample(&["--config", "transport=importance seed=5"]),
        sample(&["--transport", "importance", "--seed", "5"])
    );
    let albedo = |extra: &[&str]| albedo_at_40(&slab, "4000", extra);
    assert_eq!(
        albedo(&["--config", "max_events=3"]),
        albedo(&["--max-events", "3"])
    );
    for (config, message) in [
        (
            "rr_threshold=2",
            "--config: rr_threshold=2: expected a number from 0.001 to 1",
        ),
        ("colour=red", "--config: colour=red: unknown setting"),
        (
            "seed=1 threads=0",
            "--config: threads=0: expected a whole number",
        ),
    ] {
        for command in ["eval", "sample", "albedo"] {
            let args = match command {
                "eval" => vec!["eval", "--material", m],
                "sample" => vec!["sample", "--material", m, "--wi", "0,0,1", "--count", "1"],
                _ => vec!["albedo", "--material", m, "--theta", "0"],
            };
            let args = [&args[..], &["--config", config]].concat();
            let out = run(&args, q);
            assert_fails_with(&out, &[message]);
            assert!(out.stdout.is_empty(), "{command} --config {config}");
        }
    }
}

/// Where the limit of events ends walks, the JSON line says how many
/// (`"truncated"`): on a lossless slab of optical depth 1e4 every walk that
/// leaves has weight 1, so `R + T` is the fraction the limit did not end.
/// Under the default limit the field is absent.
#[test]
fn the_json_counts_the_walks_the_limit_ended() {
    let m = format!(
        "{}/../strata-bsdf/tests/data/lossless_slab_tau_1e4.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let args = [
        "albedo",
        "--material",
        &m,
        "--theta",
        "30",
        "--samples",
        "1000",
        "--max-events",
        "64",
    ];
    let out = assert_ok(&run(&args, ""));
    let v: Value = serde_json::from_str(out.trim()).unwrap();
    let cut = v["truncated"].as_u64().expect("a count");
    assert!(cut > 0 && cut < 1000, "{out}");
    let kept = v["R"][0].as_f64().unwrap() + v["T"][0].as_f64().unwrap();
    assert!((kept * 1000.0 - (1000 - cut) as f64).abs() < 1e-6, "{out}");
    let query = "{\"wi\":[0.3,0,1],\"wo\":[-0.2,0.1,1]}\n";
    let eval = [
        "eval",
        "--material",
        &m,
        "--samples",
        "64",
        "--max-events",
        "64",
    ];
    let out = assert_ok(&run(&eval, query));
    let v: Value = serde_json::from_str(out.trim()).unwrap();
    assert!(
        v["truncated"].as_u64().is_some_and(|n| n > 0 && n <= 64),
        "{out}"
    );
    let plain = example("scattering_slab.toml");
    let args = [
        "albedo",
        "--material",
        &plain,
        "--theta",
        "30",
        "--samples",
        "1000",
    ];
    let out = assert_ok(&run(&args, ""));
    assert!(!out.contains("truncated"), "{out}");
}
