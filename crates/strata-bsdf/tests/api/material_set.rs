//! Per-query overrides (`set`): a set applied to a base material gives the
//! stack (`==`) of a material file written with those values, for every kind
//! of parameter; every bad path or value is an error naming it.

use serde_json::{json, Value};
use strata_bsdf::query::{parse_query_line_set, parse_query_vectors, parse_sample_line, QuerySet};
use strata_bsdf::stack::{LayerStack, SetError, SetPath};

/// The base material, with one placeholder per parameter.
fn material(p: &[(&str, &str)]) -> String {
    let get = |k: &str, d: &'static str| -> String {
        p.iter()
            .find(|(n, _)| *n == k)
            .map(|(_, v)| v.to_string())
            .unwrap_or_else(|| d.to_string())
    };
    format!(
        "exterior_ior = {}\n\
         [[layers]]\ninterface = {{ kind = \"dielectric\", ior = {}, roughness = {} }}\n\
         medium = {{ thickness = {}, sigma_t = {}, albedo = {}, phase = {{ kind = \"hg\", g = {} }} }}\n\
         [[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.3 }}\n\
         [[layers]]\ninterface = {{ kind = \"conductor\", {}, roughness = {} }}\n",
        get("exterior_ior", "1"),
        get("ior", "1.5"),
        get("roughness", "0.1"),
        get("thickness", "1"),
        get("sigma_t", "0.5"),
        get("albedo", "0.8"),
        get("g", "0.3"),
        get("conductor", "preset = \"Cu\""),
        get("croughness", "0.2"),
    )
}

fn base() -> LayerStack {
    LayerStack::from_toml_str(&material(&[])).expect("base material")
}

fn set(entries: &[(&str, Value)]) -> Vec<(SetPath, Value)> {
    entries
        .iter()
        .map(|(p, v)| (p.parse().expect("a valid path"), v.clone()))
        .collect()
}

fn file(p: &[(&str, &str)]) -> LayerStack {
    LayerStack::from_toml_str(&material(p)).expect("material with the values")
}

/// Set entries, as written.
type Set = Vec<(&'static str, Value)>;
/// The file's values, by placeholder.
type Values = Vec<(&'static str, String)>;

/// The `Cu` preset's measured eta or k (column 1 or 2), as a file writes it.
fn cu(col: usize) -> String {
    let p = strata_bsdf::stack::presets::preset("Cu").expect("Cu");
    let list = |f: &dyn Fn(&(f64, f64, f64)) -> f64| {
        p.samples
            .iter()
            .map(|s| f(s).to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let v = list(&|s| if col == 1 { s.1 } else { s.2 });
    format!("{{ nm = [{}], values = [{v}] }}", list(&|s| s.0))
}

/// Every kind of parameter: the set equals the file.
#[test]
fn set_equals_file_for_every_parameter() {
    let eta_k = |e: &str, k: &str| format!("eta = {e}, k = {k}");
    let cases: Vec<(Set, Values)> = vec![
        (
            vec![("exterior_ior", json!(1.2))],
            vec![("exterior_ior", "1.2".into())],
        ),
        (
            vec![("layers[0].interface.ior", json!(1.7))],
            vec![("ior", "1.7".into())],
        ),
        (
            vec![("layers[0].interface.roughness", json!(0.25))],
            vec![("roughness", "0.25".into())],
        ),
        (
            vec![("layers[0].interface.roughness", json!([0.1, 0.2]))],
            vec![("roughness", "[0.1, 0.2]".into())],
        ),
        (
            vec![("layers[0].interface.roughness", json!(0))],
            vec![("roughness", "0".into())],
        ),
        (
            vec![("layers[0].medium.thickness", json!(0.5))],
            vec![("thickness", "0.5".into())],
        ),
        (
            vec![("layers[0].medium.sigma_t", json!(2))],
            vec![("sigma_t", "2".into())],
        ),
        (
            vec![("layers[0].medium.sigma_t", json!([0.2, 0.6, 1.2]))],
            vec![("sigma_t", "[0.2, 0.6, 1.2]".into())],
        ),
        (
            vec![("layers[0].medium.albedo", json!(0))],
            vec![("albedo", "0".into())],
        ),
        (
            vec![("layers[0].medium.albedo", json!([0.9, 0.5, 0.1]))],
            vec![("albedo", "[0.9, 0.5, 0.1]".into())],
        ),
        (
            vec![("layers[0].medium.phase.g", json!(-0.4))],
            vec![("g", "-0.4".into())],
        ),
        (
            vec![("layers[2].interface.roughness", json!([0.3, 0.05]))],
            vec![("croughness", "[0.3, 0.05]".into())],
        ),
        // The preset rule: eta replaces the preset, k comes from it; and the other way.
        (
            vec![("layers[2].interface.eta", json!([0.3, 0.5, 1.2]))],
            vec![("conductor", eta_k("[0.3, 0.5, 1.2]", &cu(2)))],
        ),
        (
            vec![("layers[2].interface.k", json!(3))],
            vec![("conductor", eta_k(&cu(1), "3"))],
        ),
        (
            vec![
                ("layers[2].interface.eta", json!(1)),
                ("layers[2].interface.k", json!(2)),
            ],
            vec![("conductor", eta_k("1", "2"))],
        ),
        (
            vec![
                ("layers[2].interface.k", json!(2)),
                ("layers[2].interface.eta", json!(1)),
            ],
            vec![("conductor", eta_k("1", "2"))],
        ),
        // Several at once, as in the issue.
        (
            vec![
                ("layers[0].medium.thickness", json!(0.5)),
                ("layers[2].interface.eta", json!([0.3, 0.5, 1.2])),
                ("layers[0].interface.roughness", json!([0.1, 0.2])),
                ("exterior_ior", json!(1.2)),
            ],
            vec![
                ("thickness", "0.5".into()),
                ("conductor", eta_k("[0.3, 0.5, 1.2]", &cu(2))),
                ("roughness", "[0.1, 0.2]".into()),
                ("exterior_ior", "1.2".into()),
            ],
        ),
    ];
    let b = base();
    for (s, values) in cases {
        let values: Vec<(&str, &str)> = values.iter().map(|(k, v)| (*k, v.as_str())).collect();
        let got = b
            .with_set(&set(&s))
            .unwrap_or_else(|e| panic!("{s:?}: {e}"));
        assert_eq!(got, file(&values), "{s:?}");
    }
    // An empty set is the stack itself.
    assert_eq!(b.with_set(&[]).expect("empty set"), b);
}

/// Conductor with explicit eta and k, and a diffuse albedo.
#[test]
fn set_equals_file_explicit_conductor_and_diffuse() {
    let c = |e: &str, k: &str| {
        LayerStack::from_toml_str(&format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5 }}\n\
             [[layers]]\ninterface = {{ kind = \"conductor\", eta = {e}, k = {k} }}\n"
        ))
        .expect("conductor")
    };
    let got = c("1", "[1, 2, 3]")
        .with_set(&set(&[("layers[1].interface.eta", json!([0.5, 0.6, 0.7]))]))
        .expect("eta");
    assert_eq!(got, c("[0.5, 0.6, 0.7]", "[1, 2, 3]"));
    let d = |a: &str| {
        LayerStack::from_toml_str(&format!(
            "[[layers]]\ninterface = {{ kind = \"diffuse\", albedo = {a} }}\n"
        ))
        .expect("diffuse")
    };
    let got = d("0.5").with_set(&set(&[(
        "layers[0].interface.albedo",
        json!([0.1, 0.2, 0.3]),
    )]));
    assert_eq!(got.expect("albedo"), d("[0.1, 0.2, 0.3]"));
}

fn err(entries: &[(&str, Value)]) -> String {
    let e = base().with_set(&set(entries)).expect_err("an invalid set");
    e.to_string()
}

/// A path that does not exist in the material names it.
#[test]
fn missing_paths_are_errors() {
    let cases = [
        (
            "layers[3].interface.ior",
            "there is no layer 3: the material has 3",
        ),
        (
            "layers[2].interface.ior",
            "layer 2's interface is a conductor, which has no `ior`",
        ),
        (
            "layers[0].interface.eta",
            "layer 0's interface is a dielectric, which has no `eta`",
        ),
        (
            "layers[0].interface.albedo",
            "is a dielectric, which has no `albedo`",
        ),
        ("layers[1].medium.thickness", "layer 1 has no medium"),
        ("layers[2].medium.albedo", "layer 2 has no medium"),
    ];
    for (p, want) in cases {
        let e = err(&[(p, json!(1))]);
        assert!(
            e.contains(&format!("`{p}`")) && e.contains(want),
            "{p}: {e}"
        );
    }
    // g of an isotropic phase.
    let iso = LayerStack::from_toml_str(
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n\
         medium = { thickness = 1, sigma_t = 1 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.5 }\n",
    )
    .expect("isotropic");
    let e = iso
        .with_set(&set(&[("layers[0].medium.phase.g", json!(0.5))]))
        .expect_err("no g");
    assert!(matches!(e, SetError::Missing { .. }), "{e}");
    assert!(
        e.to_string().contains("isotropic phase, which has no `g`"),
        "{e}"
    );
}

/// Malformed paths are errors when parsed.
#[test]
fn bad_paths_are_errors() {
    let cases = [
        (
            "layers[0].medium.thicknes",
            "unknown medium field `thicknes`",
        ),
        (
            "layers[0].interface.rougness",
            "unknown interface field `rougness`",
        ),
        ("layers[x].interface.ior", "layer index `x`"),
        ("layers[-1].interface.ior", "layer index `-1`"),
        ("layers[0.interface.ior", "without a closing `]`"),
        ("layers[0].interface.kind", "not a numeric parameter"),
        ("layers[0].interface.preset", "not a numeric parameter"),
        ("layers[0].medium.phase.kind", "not a numeric parameter"),
        ("layers[0].medium", "not whole tables"),
        ("two_sided", "not a numeric parameter"),
        ("exterior", "expected `exterior_ior`"),
        (
            "layers[99999999999999999999999].medium.thickness",
            "too large",
        ),
        ("", "expected `exterior_ior`"),
    ];
    for (p, want) in cases {
        let e = SetPath::parse(p).expect_err(p).to_string();
        assert!(
            e.contains(&format!("`{p}`")) && e.contains(want),
            "{p}: {e}"
        );
    }
    let p: SetPath = "layers[12].medium.phase.g".parse().expect("valid");
    assert_eq!(
        (p.layer(), p.field()),
        (Some(12), "medium.phase.g".to_string())
    );
    assert_eq!(p.to_string(), "layers[12].medium.phase.g");
}

/// Wrong values: the same checks and messages as a file, with the path.
#[test]
fn bad_values_are_errors() {
    let cases = [
        (
            "layers[0].medium.thickness",
            json!(-1),
            "`layers[0].medium.thickness` = -1: invalid material: layer 0: medium.thickness = -1: must be >= 0",
        ),
        (
            "layers[0].medium.albedo",
            json!([0.5, 1.5, 0.5]),
            "layer 0: medium.albedo = [0.5, 1.5, 0.5]: must be in [0, 1]",
        ),
        ("layers[0].medium.phase.g", json!(1), "medium.phase.g = 1: must be in (-1, 1)"),
        ("layers[0].interface.ior", json!(0), "layer 0: interface.ior = 0: must be > 0"),
        ("exterior_ior", json!(5000), "exterior_ior = 5000: must be in [0.001, 1000]"),
        ("layers[0].interface.roughness", json!(-0.2), "interface.roughness = -0.2: must be finite and >= 0"),
        ("layers[2].interface.eta", json!(0), "layer 2: interface.eta = [0, 0, 0]: must be > 0"),
        ("layers[2].interface.k", json!(-1), "interface.k = [-1, -1, -1]: must be >= 0"),
        ("layers[0].medium.sigma_t", json!(1e40), "gives an optical depth (thickness 1 × sigma_t)"),
        // Shapes: the field's own deserializer.
        (
            "layers[0].medium.sigma_t",
            json!([1, 2]),
            "`layers[0].medium.sigma_t` = [1,2]: invalid length 2, expected `sigma_t` to be a number or [r, g, b]",
        ),
        ("layers[0].interface.roughness", json!([1, 2, 3]), "invalid length 3, expected `roughness`"),
        ("layers[0].medium.thickness", json!([1, 2]), "`layers[0].medium.thickness` = [1,2]: invalid type"),
        ("exterior_ior", json!([1]), "`exterior_ior` = [1]: invalid type"),
        // Not numbers.
        ("layers[0].medium.thickness", json!("1"), "= \"1\": expected a number or an array of numbers"),
        ("layers[2].interface.eta", Value::Null, "= null: expected a number or an array of numbers"),
        ("layers[0].medium.albedo", json!([1, "x", 1]), "expected a number or an array of numbers"),
        ("layers[0].medium.albedo", json!({"r": 1}), "expected a number or an array of numbers"),
    ];
    for (p, v, want) in cases {
        let e = err(&[(p, v.clone())]);
        assert!(e.contains(want) && e.contains(p), "{p} = {v}: {e}");
    }
    // An error at a field not set names every entry.
    let e = err(&[
        ("layers[0].medium.thickness", json!(1e31)),
        ("layers[0].interface.ior", json!(1.4)),
    ]);
    assert!(
        e.contains("`layers[0].medium.thickness` = 1e+31, `layers[0].interface.ior` = 1.4"),
        "{e}"
    );
    // The same path twice.
    let e = err(&[("exterior_ior", json!(1)), ("exterior_ior", json!(1.1))]);
    assert_eq!(e, "set `exterior_ior`: given twice");
    // apply_set leaves the description unchanged on error.
    let mut d = base().desc().clone();
    let before = d.clone();
    let p: SetPath = "layers[0].medium.sigma_t".parse().expect("path");
    assert!(d.apply_set(&p, &json!([1, 2])).is_err());
    assert_eq!(d, before);
}

/// Query lines with and without "set".
#[test]
fn query_lines_with_set() {
    let plain = r#"{"wi":[0,0.5,1],"wo":[0.2,0,1]}"#;
    let (wi, wo, s) = parse_query_line_set(plain).expect("no set");
    assert_eq!((wi, wo), parse_query_vectors(plain).expect("plain"));
    assert!(s.is_empty());
    let line = r#"{"wi":[0,0.5,1],"wo":[0.2,0,1],"set":{"layers[0].medium.thickness":0.5,"layers[2].interface.eta":[0.3,0.5,1.2],"layers[0].interface.roughness":[0.1,0.2],"exterior_ior":1.2}}"#;
    let (wi2, wo2, s) = parse_query_line_set(line).expect("set");
    assert_eq!((wi2, wo2), (wi, wo));
    assert_eq!(s.entries().len(), 4);
    let got = s.apply(&base()).expect("valid set");
    let want = file(&[
        ("thickness", "0.5"),
        (
            "conductor",
            &format!("eta = [0.3, 0.5, 1.2], k = {}", cu(2)),
        ),
        ("roughness", "[0.1, 0.2]"),
        ("exterior_ior", "1.2"),
    ]);
    assert_eq!(got, want);
    // The old parser still refuses a line with "set" (it would ignore it).
    assert!(parse_query_vectors(line).is_err());
    // Sampling lines.
    let (w, s) = parse_sample_line(r#"{"wi":[0,0,1],"set":{"layers[0].medium.albedo":0}}"#)
        .expect("sample line");
    assert_eq!((w.z, s.entries().len()), (1.0, 1));
    assert!(parse_sample_line(r#"{"wi":[0,0,1],"wo":[0,0,1]}"#).is_err());
    assert!(parse_sample_line(r#"{"wi":[0,0,0]}"#).is_err());
}

/// Malformed "set": clear errors, never panics.
#[test]
fn malformed_sets_are_errors() {
    let q = |set: &str| {
        parse_query_line_set(&format!(r#"{{"wi":[0,0,1],"wo":[0,0,1],"set":{set}}}"#))
            .expect_err(set)
            .to_string()
    };
    let cases = [
        ("3", "expected an object from paths to values"),
        ("[1,2]", "expected an object from paths to values"),
        ("\"x\"", "expected an object from paths to values"),
        (
            r#"{"layers[0].medium.thickness":"0.5"}"#,
            "expected a number or an array of numbers",
        ),
        (
            r#"{"layers[0].medium.thickness":true}"#,
            "expected a number or an array of numbers",
        ),
        (
            r#"{"layers[0].medium.thickness":{}}"#,
            "expected a number or an array of numbers",
        ),
        (
            r#"{"layers[0].medium.thicknes":1}"#,
            "unknown medium field `thicknes`",
        ),
        (r#"{"layers[0].medium.thickness":NaN}"#, "invalid query"),
    ];
    for (set, want) in cases {
        let e = q(set);
        assert!(e.contains(want), "{set}: {e}");
    }
    assert!(QuerySet::from_json(&json!({})).expect("empty").is_empty());
}
