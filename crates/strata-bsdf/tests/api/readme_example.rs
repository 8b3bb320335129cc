//! The library example of README.md, compiled and run. The code between the
//! markers below must be identical to the README's `rust` block (checked by
//! `readme_shows_this_example`).

#[test]
fn readme_example() -> Result<(), Box<dyn std::error::Error>> {
    // README example start
    use strata_bsdf::{Bsdf, Column, LayerStack, LayeredBsdf, PerQuery, Queries};

    // A rough varnish with a tinted absorber over rough copper.
    let stack = LayerStack::from_toml_str(
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
        medium = { thickness = 0.5, sigma_t = [0.2, 0.6, 1.2], albedo = 0.0 }
        [[layers]]
        interface = { kind = "conductor", preset = "Cu", roughness = 0.2 }
        "#,
    )?;
    let bsdf = LayeredBsdf::new(stack).samples(1024).seed(7);

    // Local frame: z is the normal; wi (to the light) and wo (to the viewer)
    // both point away from the surface.
    let wi = glam::Vec3::new(0.5, 0.0, 0.866);
    let wo = glam::Vec3::new(-0.5, 0.0, 0.866);

    let f = bsdf.eval(wi, wo)?; // f(wi, wo) in 1/sr, without the cosine
    println!("f = {:?} ± {:?}", f.value, f.stderr);

    if let Some(s) = bsdf.sample(wi, 0)? {
        // s.weight = f(wi, s.wo) |cos θo| / pdf, an unbiased estimate; s.pdf is
        // exactly bsdf.pdf(wi, s.wo), for MIS
        let (wo, w, p) = (s.wo, s.weight, s.pdf);
        println!("sampled {wo:?} with weight {w:?}, pdf {p}");
        assert_eq!(s.pdf, bsdf.pdf(wi, s.wo)?);
    }
    let pdf = bsdf.pdf(wi, wo)?; // the density sample() carries, for MIS
    let a = bsdf.albedo(wi, 10_000)?; // reflected and transmitted fractions
    let (r, t) = (a.reflected.value, a.transmitted.value);
    println!("pdf = {pdf}, R = {r:?}, T = {t:?}");

    // A batch, each query with its own coat thickness (a texture).
    let path = "layers[0].medium.thickness".parse()?;
    let thickness = [0.1f32, 0.5, 2.0];
    let texture = [Column {
        path: &path,
        width: 1,
        values: &thickness,
    }];
    let rows = PerQuery::new(&bsdf, 3, &texture)?;
    let (wis, wos) = ([wi; 3], [wo; 3]);
    let q = Queries::pairs(&wis[..], &wos[..]);
    let mut fs = [[0.0; 3]; 3];
    rows.eval_into(&q, &mut |k, e| fs[k] = e.value)?;
    // README example end

    // What the example claims, checked.
    assert!(f.value.iter().all(|v| v.is_finite() && *v > 0.0));
    assert!(f.stderr.iter().zip(f.value).all(|(e, v)| *e < 0.1 * v));
    assert!(pdf.is_finite() && pdf > 0.0);
    assert_eq!(a.transmitted.value, [0.0; 3], "copper is opaque");
    assert!(a.reflected.value.iter().all(|r| *r > 0.05 && *r < 1.0));
    // A thicker tinted coat absorbs more (its blue most), and query 1's
    // thickness is the material's own: its answer is the plain eval's.
    assert!(fs[0][2] > fs[1][2] && fs[1][2] > fs[2][2], "{fs:?}");
    assert_eq!(fs[1], f.value);
    Ok(())
}

/// The README's `rust` block is the code between the markers above.
#[test]
fn readme_shows_this_example() {
    let this = include_str!("readme_example.rs");
    let start = this
        .find("// README example start\n")
        .expect("start marker")
        + 24;
    let end = this.find("    // README example end").expect("end marker");
    let code: Vec<&str> = this[start..end]
        .lines()
        .map(|l| l.strip_prefix("    ").unwrap_or(l))
        .collect();
    let readme = include_str!("../../../../README.md");
    let block = readme
        .split("```rust\n")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .expect("README has a ```rust block");
    let block: Vec<&str> = block.lines().collect();
    assert_eq!(
        block, code,
        "README's example differs from tests/api/readme_example.rs"
    );
}
