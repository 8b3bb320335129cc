//! Spectra in material files (issue 42): every coloured field takes a
//! tabulated spectrum and a dielectric's `ior` also a Cauchy or Abbe law, in
//! TOML and JSON; the stack holds their RGB numbers (the CIE reduction; n at
//! the d line for an IOR) and the description keeps the spectra, writing
//! them back out as read; every bad spectrum is an error naming the field,
//! the sample and the value.

use strata_bsdf::stack::{presets, InterfaceDesc, LayerStack, MaterialDesc, Spectrum};

const ALBEDO: &str = "{ nm = [400, 500, 600, 700], values = [0.2, 0.4, 0.6, 0.8] }";
const SIGMA_T: &str = "{ nm = [450, 650], values = [2, 0.5] }";
const ETA: &str = "{ nm = [400, 700], values = [1.2, 0.3] }";
const K: &str = "{ nm = [400.0, 550.0, 700.0], values = [2, 2.5, 4] }";

/// A coat with a medium over a conductor, the fields given.
fn stack_toml(ior: &str, sigma_t: &str, albedo: &str, eta: &str, k: &str) -> String {
    format!(
        "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = {ior}, roughness = 0.1 }}\n\
         medium = {{ thickness = 1, sigma_t = {sigma_t}, albedo = {albedo} }}\n\
         [[layers]]\ninterface = {{ kind = \"conductor\", eta = {eta}, k = {k} }}\n"
    )
}

fn tab(nm: &[f64], values: &[f64]) -> Spectrum {
    Spectrum::Tabulated {
        nm: nm.to_vec(),
        values: values.to_vec(),
    }
}

/// Every form parses, in TOML and in JSON, to the same description; the
/// stack's numbers are the spectra's RGB numbers; the description writes
/// back out (TOML and JSON) to itself.
#[test]
fn every_form_parses_in_toml_and_json() {
    let iors = [
        ("1.5", Spectrum::Grey(1.5)),
        (
            "{ nm = [400, 700], values = [1.53, 1.51] }",
            tab(&[400.0, 700.0], &[1.53, 1.51]),
        ),
        (
            "{ cauchy = [1.5046, 0.0042] }",
            Spectrum::Cauchy {
                cauchy: [1.5046, 0.0042],
            },
        ),
        (
            "{ nd = 1.5168, abbe = 64.17 }",
            Spectrum::Abbe {
                nd: 1.5168,
                abbe: 64.17,
            },
        ),
    ];
    for (text, ior) in iors {
        let toml = stack_toml(text, SIGMA_T, ALBEDO, ETA, K);
        let st = LayerStack::from_toml_str(&toml).unwrap_or_else(|e| panic!("{text}: {e}"));
        let d = st.desc();
        let InterfaceDesc::Dielectric { ior: got, .. } = &d.layers[0].interface else {
            panic!("a dielectric");
        };
        assert_eq!(got, &ior);
        assert_eq!(st.interface(0).n_below, ior.d_line(), "{text}");
        let m = st.medium(0).expect("a medium");
        let (sigma_t, albedo) = (
            tab(&[450.0, 650.0], &[2.0, 0.5]),
            tab(&[400.0, 500.0, 600.0, 700.0], &[0.2, 0.4, 0.6, 0.8]),
        );
        assert_eq!(m.sigma_t, sigma_t.rgb());
        assert_eq!(m.albedo, albedo.rgb());
        let (eta, k) = (
            tab(&[400.0, 700.0], &[1.2, 0.3]),
            tab(&[400.0, 550.0, 700.0], &[2.0, 2.5, 4.0]),
        );
        // The conductor's constants relative to the coat above, at the d line.
        let n = ior.d_line();
        assert_eq!(st.interface(1).eta, eta.rgb().map(|x| x / n));
        assert_eq!(st.interface(1).k, k.rgb().map(|x| x / n));
        // A reddish albedo: more red than blue; the extinction the other way.
        assert!(m.albedo[0] > m.albedo[2] && m.sigma_t[0] < m.sigma_t[2]);

        // JSON, and both serializations, read back to the same description.
        let json = serde_json::to_string(d).expect("to JSON");
        let from_json = LayerStack::from_json_str(&json).expect("JSON");
        assert_eq!(&from_json, &st, "{json}");
        let toml_out = toml::to_string(d).expect("to TOML");
        let back: MaterialDesc = toml::from_str(&toml_out).expect("TOML back");
        assert_eq!(&back, d, "{toml_out}");
    }
    // The JSON forms, written by hand.
    let json = r#"{"layers":[
        {"interface":{"kind":"dielectric","ior":{"nd":1.5168,"abbe":64.17}},
         "medium":{"thickness":1,"sigma_t":{"nm":[450,650],"values":[2,0.5]},
                   "albedo":{"nm":[400,500,600,700],"values":[0.2,0.4,0.6,0.8]}}},
        {"interface":{"kind":"diffuse","albedo":{"nm":[500],"values":[0.3]}}}]}"#;
    let st = LayerStack::from_json_str(json).expect("JSON spectra");
    assert_eq!(st.interface(1).albedo, [0.3; 3]);
    assert_eq!(st.interface(0).n_below, 1.5168);
    let json = r#"{"layers":[{"interface":{"kind":"conductor","eta":{"nm":[400,700],"values":[1.2,0.3]},"k":{"nm":[400,550,700],"values":[2,2.5,4]}}}]}"#;
    let st = LayerStack::from_json_str(json).expect("JSON conductor");
    assert_eq!(st.interface(0).eta, tab(&[400.0, 700.0], &[1.2, 0.3]).rgb());
    // An old-style file parses exactly as before: numbers stay numbers.
    let st = LayerStack::from_toml_str(&stack_toml(
        "1.5",
        "[1, 2, 3]",
        "0.5",
        "[0.2, 0.9, 1.1]",
        "3",
    ))
    .expect("RGB");
    assert_eq!(st.medium(0).expect("medium").sigma_t, [1.0, 2.0, 3.0]);
    assert_eq!(st.interface(1).k, [2.0; 3]);
}

/// A preset is its measured spectra: the file with those spectra written
/// out gives the same numbers.
#[test]
fn presets_are_their_spectra_in_files() {
    for p in presets::PRESETS {
        let list = |v: Vec<f64>| {
            v.iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let written = |s: Spectrum| match s {
            Spectrum::Tabulated { nm, values } => {
                format!("{{ nm = [{}], values = [{}] }}", list(nm), list(values))
            }
            other => panic!("a preset is tabulated: {other:?}"),
        };
        let by_name = LayerStack::from_toml_str(&format!(
            "[[layers]]\ninterface = {{ kind = \"conductor\", preset = \"{}\" }}\n",
            p.name
        ))
        .expect("preset");
        let by_value = LayerStack::from_toml_str(&format!(
            "[[layers]]\ninterface = {{ kind = \"conductor\", eta = {}, k = {} }}\n",
            written(p.eta()),
            written(p.k())
        ))
        .expect("spectra");
        assert_eq!(by_name.interface(0), by_value.interface(0), "{}", p.name);
    }
}

fn error(toml: &str) -> String {
    LayerStack::from_toml_str(toml)
        .expect_err("an invalid material")
        .to_string()
}

/// Every problem with a spectrum is reported with the field, the sample and
/// the value.
#[test]
fn bad_spectra_are_errors_naming_the_sample() {
    let diffuse = |albedo: &str| {
        format!("[[layers]]\ninterface = {{ kind = \"diffuse\", albedo = {albedo} }}\n")
    };
    let medium = |sigma_t: &str, albedo: &str| {
        format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5 }}\n\
             medium = {{ thickness = 1e20, sigma_t = {sigma_t}, albedo = {albedo} }}\n\
             [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n"
        )
    };
    let conductor = |eta: &str, k: &str| {
        format!("[[layers]]\ninterface = {{ kind = \"conductor\", eta = {eta}, k = {k} }}\n")
    };
    let dielectric =
        |ior: &str| format!("[[layers]]\ninterface = {{ kind = \"dielectric\", ior = {ior} }}\n");
    let cases = [
        (
            diffuse("{ nm = [], values = [] }"),
            "invalid material: layer 0: interface.albedo.nm: the spectrum has no samples: give at least one wavelength and its value",
        ),
        (
            diffuse("{ nm = [400, 500], values = [0.5] }"),
            "invalid material: layer 0: interface.albedo.values: 1 values for 2 wavelengths: give one value per wavelength of `nm`",
        ),
        (
            diffuse("{ nm = [400, 500, 450], values = [0.5, 0.5, 0.5] }"),
            "invalid material: layer 0: interface.albedo.nm[2] = 450: the wavelengths must be strictly increasing (nm[1] = 500)",
        ),
        (
            diffuse("{ nm = [400, 400], values = [0.5, 0.5] }"),
            "invalid material: layer 0: interface.albedo.nm[1] = 400: the wavelengths must be strictly increasing (nm[0] = 400)",
        ),
        (
            diffuse("{ nm = [400, nan], values = [0.5, 0.5] }"),
            "invalid material: layer 0: interface.albedo.nm[1] = NaN: must be a finite number",
        ),
        (
            diffuse("{ nm = [400, 500, 600], values = [0.5, 1.5, 0.5] }"),
            "invalid material: layer 0: interface.albedo.values[1] = 1.5: must be in [0, 1]",
        ),
        (
            diffuse("{ nm = [400, 500], values = [0.5, inf] }"),
            "invalid material: layer 0: interface.albedo.values[1] = inf: must be a finite number",
        ),
        (
            medium("{ nm = [400, 500], values = [1, -1] }", "1"),
            "invalid material: layer 0: medium.sigma_t.values[1] = -1: must be >= 0",
        ),
        (
            medium("{ nm = [400, 500], values = [1, 1e11] }", "1"),
            "invalid material: layer 0: medium.sigma_t.values[1] = 100000000000: gives an optical depth (thickness 100000000000000000000 × sigma_t) above 1000000000000000000000000000000",
        ),
        (
            medium("1e-30", "{ nm = [400], values = [-0.1] }"),
            "invalid material: layer 0: medium.albedo.values[0] = -0.1: must be in [0, 1]",
        ),
        (
            conductor("{ nm = [400, 500], values = [1, 0] }", "1"),
            "invalid material: layer 0: interface.eta.values[1] = 0: must be > 0",
        ),
        (
            conductor("1", "{ nm = [400, 500], values = [1, -2] }"),
            "invalid material: layer 0: interface.k.values[1] = -2: must be >= 0",
        ),
        (
            conductor("1", "{ nm = [400, 500], values = [1, 2e6] }"),
            "invalid material: layer 0: interface.k.values[1] = 2000000: must be at most 1000000",
        ),
        (
            dielectric("{ nm = [400, 500], values = [1.5, 0] }"),
            "invalid material: layer 0: interface.ior.values[1] = 0: must be > 0",
        ),
        (
            dielectric("{ nm = [400, 500], values = [1.5, 2000] }"),
            "invalid material: layer 0: interface.ior.values[1] = 2000: must be in [0.001, 1000]",
        ),
        (
            dielectric("{ cauchy = [1.5, nan] }"),
            "invalid material: layer 0: interface.ior.cauchy = [1.5, NaN]: must be finite numbers",
        ),
        (
            dielectric("{ cauchy = [-1, 0.01] }"),
            "invalid material: layer 0: interface.ior.cauchy = [-1, 0.01]: gives n = -0.9228395061728395 at 360 nm, which must be > 0",
        ),
        (
            dielectric("{ nd = 1.5, abbe = 0 }"),
            "invalid material: layer 0: interface.ior.abbe = 0: must be a finite number > 0",
        ),
        (
            dielectric("{ nd = 0, abbe = 30 }"),
            "invalid material: layer 0: interface.ior.nd = 0: must be > 0",
        ),
        (
            dielectric("{ nd = 1.5, abbe = 1e-6 }"),
            "invalid material: layer 0: interface.ior = { nd = 1.5, abbe = 0.000001 }: gives n = ",
        ),
    ];
    for (toml, want) in &cases {
        let e = error(toml);
        assert!(e.starts_with(want), "{toml}\n got: {e}\nwant: {want}");
    }
}

/// Forms a field does not take, unknown and mixed keys, and wrong types
/// are parse errors that name the field.
/// A spectrum whose reduction to RGB overflows (values near `f64::MAX`
/// under a tiny thickness: an ordinary optical depth) is an error naming
/// the field, not an extinction clamped to 0.
#[test]
fn a_reduction_that_overflows_is_an_error() {
    let e = error(
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n\
         medium = { thickness = 1e-300, sigma_t = { nm = [400, 700], values = [0, 1e308] }, albedo = 0 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.5 }\n",
    );
    assert!(e.contains("sigma_t"), "{e}");
}

#[test]
fn wrong_forms_are_parse_errors() {
    let cases = [
        (
            "interface = { kind = \"diffuse\", albedo = { cauchy = [1.5, 0.01] } }",
            "`albedo`: unknown field `cauchy` of a spectrum, expected `nm`, `values`",
        ),
        (
            "interface = { kind = \"dielectric\", ior = [1.5, 1.5, 1.5] }",
            "invalid type: sequence, expected `ior` to be a number, or a spectrum: { nm = [...], values = [...] }, { cauchy = [A, B] } or { nd = N, abbe = V }",
        ),
        (
            "interface = { kind = \"dielectric\", ior = { nm = [500], values = [1.5], cauchy = [1, 0] } }",
            "`ior`: a spectrum is { nm = [...], values = [...] }, { cauchy = [A, B] } or { nd = N, abbe = V }; got the fields ", // (in the parser's order)
        ),
        (
            "interface = { kind = \"dielectric\", ior = { nd = 1.5 } }",
            "got the fields `nd`",
        ),
        (
            "interface = { kind = \"diffuse\", albedo = { nm = [500] } }",
            "`albedo`: a spectrum is { nm = [...], values = [...] }; got the fields `nm`",
        ),
        (
            "interface = { kind = \"diffuse\", albedo = { nm = [500], values = [\"x\"] } }",
            "`albedo.values`: invalid type: string \"x\", expected f64",
        ),
        (
            "interface = { kind = \"conductor\", eta = 1, k = { nm = 500, values = [1] } }",
            "`k.nm`: invalid type: integer `500`, expected a sequence",
        ),
        (
            "interface = { kind = \"dielectric\", ior = { cauchy = [1.5] } }",
            "`ior.cauchy`: invalid length 1, expected an array of length 2",
        ),
        (
            "interface = { kind = \"diffuse\", albedo = \"red\" }",
            "expected `albedo` to be a number or [r, g, b], or a spectrum { nm = [...], values = [...] }",
        ),
    ];
    for (layer, want) in cases {
        let e = error(&format!("[[layers]]\n{layer}\n"));
        assert!(e.contains(want), "{layer}\n got: {e}\nwant: {want}");
    }
    // A dispersion law built in code for a coloured field is an error, not a panic.
    let mut d: MaterialDesc =
        toml::from_str("[[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.5 }\n")
            .expect("desc");
    if let InterfaceDesc::Diffuse { albedo, .. } = &mut d.layers[0].interface {
        *albedo = Spectrum::Abbe {
            nd: 1.5,
            abbe: 40.0,
        };
    }
    let e = LayerStack::new(&d)
        .expect_err("a law as an albedo")
        .to_string();
    assert!(e.contains("interface.albedo: a dispersion law"), "{e}");
    if let InterfaceDesc::Diffuse { albedo, .. } = &mut d.layers[0].interface {
        *albedo = Spectrum::Grey(0.5);
    }
    assert!(LayerStack::new(&d).is_ok());
}

/// Setting `eta` or `k` of a preset conductor leaves the other the
/// preset's measured spectrum, as a file writes it.
#[test]
fn set_on_a_preset_keeps_its_spectrum() {
    let base = LayerStack::from_toml_str(
        "[[layers]]\ninterface = { kind = \"conductor\", preset = \"Au\" }\n",
    )
    .expect("gold");
    let set = [(
        "layers[0].interface.eta".parse().expect("path"),
        serde_json::json!([0.2, 0.4, 1.3]),
    )];
    let st = base.with_set(&set).expect("set");
    let InterfaceDesc::Conductor { preset, eta, k, .. } = &st.desc().layers[0].interface else {
        panic!("a conductor");
    };
    let au = presets::preset("Au").expect("Au");
    assert_eq!(preset, &None);
    assert_eq!(eta, &Some(Spectrum::Rgb([0.2, 0.4, 1.3])));
    assert_eq!(k, &Some(au.k()));
    assert_eq!(st.interface(0).k, base.interface(0).k);
}
