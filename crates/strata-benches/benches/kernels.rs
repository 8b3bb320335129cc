//! Kernels, scalar against lanes: the same generic code on `f32` (one walk)
//! and on `F32x8` / `F32x16` (eight or sixteen walks per call). Inputs are
//! pre-generated with a fixed seed; throughput is reported per direction, so
//! the lane rows' speed-up over the scalar row reads off directly.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::hint::black_box;
use strata_bsdf::lane::{F32x16, F32x8, Lane, LaneMask, Wide, V3};
use strata_bsdf::medium;
use strata_bsdf::rng::{Stream, WalkRng};

const N: usize = 4096;

fn inputs() -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let mut rng = WalkRng::new(1, 2, 3, Stream::Walk);
    let mut dir = || {
        let z = 0.05 + 0.95 * rng.uniform();
        let p = std::f32::consts::TAU * rng.uniform();
        let r = (1.0 - z * z).sqrt();
        [r * p.cos(), r * p.sin(), z]
    };
    let a: Vec<[f32; 3]> = (0..N).map(|_| dir()).collect();
    let u: Vec<[f32; 3]> = (0..N).map(|_| dir()).collect();
    (a, u)
}

/// The directions in lane-sized groups, built before timing so that the timed
/// loops read ready lanes (a per-iteration gather would cost the lane rows
/// eight inserts per component, which the scalar row does not pay).
fn lanes<L: Lane>(v: &[[f32; 3]]) -> Vec<V3<L>> {
    (0..v.len())
        .step_by(L::LANES)
        .map(|i| {
            let c = |k: usize| L::from_fn(|j| v[i + j][k] as f64);
            V3::new(c(0), c(1), c(2))
        })
        .collect()
}

fn bench_interface<L: Lane>(c: &mut Criterion, name: &str, toml: &str, label: &str) {
    let stack = strata_bsdf::LayerStack::from_toml_str(toml).unwrap();
    let iface = stack.interface_lanes::<L>(0);
    let (a, u) = inputs();
    let (a, u) = (lanes::<L>(&a), lanes::<L>(&u));
    let mut g = c.benchmark_group(format!("kernel/{name}"));
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function(BenchmarkId::new("sample", label), |b| {
        b.iter(|| {
            let mut acc = L::zero();
            for (&w, &r) in a.iter().zip(&u) {
                let s = iface.sample(w, r.x.abs(), r.y.abs(), r.z, L::Mask::splat(false));
                acc += s.weight.r + s.b.z;
            }
            black_box(acc)
        })
    });
    g.bench_function(BenchmarkId::new("eval+pdf", label), |b| {
        b.iter(|| {
            let mut acc = L::zero();
            for (&w, &o) in a.iter().zip(&u) {
                acc += iface.eval(w, o).r + iface.pdf(w, o, L::Mask::splat(false));
            }
            black_box(acc)
        })
    });
    g.finish();
}

fn bench_medium<L: Lane>(c: &mut Criterion, label: &str) {
    let (a, u) = inputs();
    let (a, u) = (lanes::<L>(&a), lanes::<L>(&u));
    let st = strata_bsdf::lane::Rgb::<L>::from_array([1.0, 2.0, 3.0]);
    let al = strata_bsdf::lane::Rgb::<L>::from_array([0.9, 0.8, 0.7]);
    let mut g = c.benchmark_group("kernel/medium");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function(BenchmarkId::new("free_flight+hg_sample", label), |b| {
        b.iter(|| {
            let mut acc = L::zero();
            for (&d, &r) in a.iter().zip(&u) {
                let ff = medium::free_flight(
                    st,
                    al,
                    L::one(),
                    r.z * L::splat(2.9),
                    r.x.abs(),
                    strata_bsdf::lane::Rgb::one(),
                );
                let dn = strata_bsdf::phase::hg::hg_sample(L::splat(0.5), d, r.x.abs(), r.y.abs());
                acc += ff.weight.g + dn.z;
            }
            black_box(acc)
        })
    });
    g.finish();
}

const ROUGH_DIELECTRIC: &str = r#"
    [[layers]]
    interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
"#;
const ROUGH_CONDUCTOR: &str = r#"
    [[layers]]
    interface = { kind = "conductor", preset = "Cu", roughness = 0.2 }
"#;

fn kernels(c: &mut Criterion) {
    for (name, toml) in [
        ("rough_dielectric", ROUGH_DIELECTRIC),
        ("rough_conductor", ROUGH_CONDUCTOR),
    ] {
        bench_interface::<f32>(c, name, toml, "f32");
        bench_interface::<F32x8>(c, name, toml, "f32x8");
        bench_interface::<F32x16>(c, name, toml, "f32x16");
    }
    bench_medium::<f32>(c, "f32");
    bench_medium::<F32x8>(c, "f32x8");
    bench_medium::<F32x16>(c, "f32x16");
    // Keep `Wide` in use so the lane types stay the wavefront's.
    let _ = <F32x8 as Wide>::bitmask;
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_millis(500)).measurement_time(std::time::Duration::from_secs(2));
    targets = kernels
}
criterion_main!(benches);
