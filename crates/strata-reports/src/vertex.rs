//! One shading vertex of a path tracer, as pbrt-v4's `PathIntegrator` makes
//! it: what a renderer pays for a layered material, against pbrt-v4's
//! `LayeredBxDF` measured the same way (`data/pbrt-v4/vertex.csv`, its
//! README says how).
//!
//! The scene of a vertex: the view at polar 10°, 45° or 75° (azimuth 0), a
//! sky of radiance 1 over the whole sphere reached by the BSDF sample only,
//! and a sun, a cone of half-angle 3° around polar 40°, azimuth 180°, of
//! radiance 200, sampled uniformly (light pdf `p_l = 1/Ω`). One vertex adds
//!
//! * one BSDF sample from the view: `w (1 + 200 [in sun] p_b² / (p_b² + p_l²))`,
//!   `w = f |cos| / p`, with MIS weight 1 for a delta sample, and
//! * one light sample: `f |cos| 200 / p_l · p_l² / (p_l² + p_b²)`,
//!
//! and its scalar is the mean of the three channels. strata answers batches
//! of vertices on one thread with one walk per eval, keyed per vertex (fresh
//! randomness), in importance mode (the view is `wi`), through the slice
//! calls (a sample, then the light sample's eval and pdf in one call); the
//! time is the thread's CPU time of the calls. Efficiency is `1 / (variance × time per vertex)`.

use crate::pbrt::{self, Config};
use glam::Vec3;
use std::f64::consts::PI;
use strata_bsdf::stack::SetPath;
use strata_bsdf::{
    Bsdf, Column, Estimate, LayerStack, LayeredBsdf, PerQuery, Queries, SampleBuffers, Transport,
    Vectors, VectorsMut,
};

const DATA: &str = include_str!("../data/pbrt-v4/vertex.csv");

/// The views of the benchmark, polar angles in degrees.
pub const VIEWS: [f64; 3] = [10.0, 45.0, 75.0];
/// The sun's radiance.
pub const SUN_RADIANCE: f64 = 200.0;
/// The sun's half-angle, in degrees.
pub const SUN_HALF_ANGLE: f64 = 3.0;
/// The sun's polar angle and azimuth, in degrees.
pub const SUN_POLAR: f64 = 40.0;
/// The sun's azimuth, in degrees.
pub const SUN_AZIMUTH: f64 = 180.0;

/// The sun's solid angle, `2π (1 − cos 3°)`.
pub fn sun_solid_angle() -> f64 {
    2.0 * PI * (1.0 - SUN_HALF_ANGLE.to_radians().cos())
}

fn sun_axis() -> [f64; 3] {
    let (t, p) = (SUN_POLAR.to_radians(), SUN_AZIMUTH.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

/// The view direction at polar `deg` (azimuth 0).
pub fn view(deg: f64) -> [f64; 3] {
    let t = deg.to_radians();
    [t.sin(), 0.0, t.cos()]
}

/// Whether `d` (unit) lies in the sun's cone.
pub fn in_sun(d: [f64; 3]) -> bool {
    let a = sun_axis();
    let c = d[0] * a[0] + d[1] * a[1] + d[2] * a[2];
    c >= SUN_HALF_ANGLE.to_radians().cos()
}

/// A direction uniform in the sun's cone from two uniforms in [0, 1).
pub fn sun_direction(u1: f64, u2: f64) -> [f64; 3] {
    let cos_max = SUN_HALF_ANGLE.to_radians().cos();
    let c = 1.0 - u1 * (1.0 - cos_max);
    let s = (1.0 - c * c).max(0.0).sqrt();
    let phi = 2.0 * PI * u2;
    let local = [s * phi.cos(), s * phi.sin(), c];
    // A frame around the axis: the axis lies in the xz-plane (azimuth 180°).
    let z = sun_axis();
    let x = [z[2], 0.0, -z[0]];
    let y = [
        z[1] * x[2] - z[2] * x[1],
        z[2] * x[0] - z[0] * x[2],
        z[0] * x[1] - z[1] * x[0],
    ];
    std::array::from_fn(|i| local[0] * x[i] + local[1] * y[i] + local[2] * z[i])
}

/// pbrt-v4's measurement of one configuration and view.
#[derive(Clone, Copy, Debug)]
pub struct PbrtVertex {
    /// Mean of the vertex scalar.
    pub mean: f64,
    /// Its standard error.
    pub stderr: f64,
    /// Per-vertex variance.
    pub variance: f64,
    /// Thread-CPU nanoseconds per vertex (median over rounds).
    pub ns_per_vertex: f64,
}

/// pbrt-v4's vertex of configuration `name` at the view `deg`, if measured.
pub fn pbrt_vertex(name: &str, deg: f64) -> Option<PbrtVertex> {
    let mut lines = DATA.lines();
    let header: Vec<&str> = lines.next()?.split(',').collect();
    let col = |h: &str| header.iter().position(|c| *c == h);
    let (c_cfg, c_view) = (col("config")?, col("view_theta_deg")?);
    let (c_mean, c_se, c_var, c_ns) = (
        col("mean")?,
        col("stderr")?,
        col("variance")?,
        col("ns_per_vertex_median")?,
    );
    lines
        .map(|l| l.split(',').collect::<Vec<&str>>())
        .find(|v| v[c_cfg] == name && v[c_view].parse::<f64>().ok() == Some(deg))
        .and_then(|v| {
            let num = |i: usize| v[i].parse::<f64>().ok();
            Some(PbrtVertex {
                mean: num(c_mean)?,
                stderr: num(c_se)?,
                variance: num(c_var)?,
                ns_per_vertex: num(c_ns)?,
            })
        })
}

/// strata's side of one configuration and view.
#[derive(Clone, Copy, Debug)]
pub struct VertexRun {
    /// Vertices estimated.
    pub vertices: u64,
    /// Mean of the vertex scalar.
    pub mean: f64,
    /// Per-vertex variance.
    pub variance: f64,
    /// Thread-CPU nanoseconds per vertex of the library's calls.
    pub ns_per_vertex: f64,
    /// Of which: the per-vertex tables of the two calls (textured; 0
    /// otherwise), the sample call's and the light sample's eval and pdf
    /// call's.
    pub ns_per_call: [f64; 3],
}

impl VertexRun {
    /// The standard error of the mean.
    pub fn stderr(&self) -> f64 {
        (self.variance / self.vertices as f64).sqrt()
    }

    /// Efficiency over pbrt-v4's: `(var_p t_p) / (var_s t_s)`.
    pub fn ratio(&self, p: &PbrtVertex) -> f64 {
        (p.variance * p.ns_per_vertex) / (self.variance * self.ns_per_vertex)
    }
}

/// The BSDF a renderer makes of configuration `c`: importance mode (the
/// view is `wi`), one walk per eval, one thread, the library's other
/// defaults.
pub fn renderer_bsdf(c: &Config) -> Result<LayeredBsdf, String> {
    let stack = LayerStack::from_toml_str(&c.toml).map_err(|e| format!("{}: {e}", c.name))?;
    LayeredBsdf::new(stack)
        .transport(Transport::Importance)
        .samples(1)
        .threads(1)
        .map_err(|e| e.to_string())
}

/// Per-vertex parameters, as a renderer's textures give them: every vertex
/// its own coat thickness, absorption (RGB), the coat's roughness where it
/// is rough and the base's albedo where it is Lambertian, each within ±1 %
/// of the configuration's own value.
#[derive(Clone, Debug)]
pub struct Texture {
    columns: Vec<(SetPath, usize, f32)>,
    values: Vec<Vec<f32>>,
}

impl Texture {
    /// The columns configuration `c` takes (its own values beside them).
    pub fn new(c: &Config) -> Self {
        let path = |p: &str| p.parse::<SetPath>().expect("a parameter path");
        let mut columns = vec![
            (path("layers[0].medium.thickness"), 1, 0.01),
            (path("layers[0].medium.sigma_t"), 3, 1.0),
        ];
        if c.toml.contains("roughness = 0.1") {
            columns.push((path("layers[0].interface.roughness"), 1, 0.1));
        }
        if c.toml.contains("\"diffuse\"") {
            columns.push((path("layers[1].interface.albedo"), 3, 0.8));
        }
        Texture {
            columns,
            values: Vec::new(),
        }
    }

    /// The names of its parameters.
    pub fn paths(&self) -> Vec<String> {
        self.columns.iter().map(|c| c.0.to_string()).collect()
    }

    /// Fresh values for `n` vertices: every value of every vertex its own,
    /// within 1 % of the material's. (Distinct rows cost what any texture
    /// costs; a wider spread would add the texture's own variation to the
    /// vertex's variance, which is the image's content, not the estimator's
    /// noise, and the efficiency ratio is of the estimator.)
    pub fn draw(&mut self, n: usize, rng: &mut u64) {
        self.values = (self.columns.iter())
            .map(|&(_, width, own)| {
                let jitter = |r: &mut u64| own * (0.99 + 0.02 * uniform(r) as f32);
                (0..width * n).map(|_| jitter(rng)).collect()
            })
            .collect();
    }

    /// Its columns for the last [`Texture::draw`]: per parameter, its path,
    /// its width (1 or 3) and `width × n` values.
    pub fn columns(&self) -> Vec<Column<'_>> {
        (self.columns.iter().zip(&self.values))
            .map(|((path, width, _), values)| Column {
                path,
                width: *width,
                values,
            })
            .collect()
    }
}

/// The buffers of one batch of vertices.
struct Batch {
    wi: Vec<f32>,
    keys: Vec<u64>,
    wo: Vec<f32>,
    weight: Vec<f32>,
    pdf: Vec<f32>,
    flags: Vec<u32>,
    light: Vec<f32>,
    light_keys: Vec<u64>,
    f: Vec<f32>,
    light_pdf: Vec<f32>,
}

impl Batch {
    fn new(n: usize, view: [f64; 3]) -> Self {
        let v = view.map(|x| x as f32);
        Batch {
            wi: (0..n).flat_map(|_| v).collect(),
            keys: vec![0; n],
            wo: vec![0.0; 3 * n],
            weight: vec![0.0; 3 * n],
            pdf: vec![0.0; n],
            flags: vec![0; n],
            light: vec![0.0; 3 * n],
            light_keys: vec![0; n],
            f: vec![0.0; 3 * n],
            light_pdf: vec![0.0; n],
        }
    }

    /// The two calls of a batch of vertices: sample, and eval and pdf of
    /// the light samples in one call, on the BSDF's own parameters or, with
    /// a texture, on per-vertex columns, which each call takes (as the C
    /// ABI's and Python's per-query calls do: the thread's kept table serves
    /// the second); their CPU times, the tables' first, are added to `ns`.
    fn run(
        &mut self,
        bsdf: &LayeredBsdf,
        texture: Option<&Texture>,
        ns: &mut [f64; 3],
    ) -> Result<(), String> {
        let e = |e: strata_bsdf::BatchError| e.to_string();
        let n = self.keys.len();
        let columns = texture.map(Texture::columns).unwrap_or_default();
        let mut table = 0.0;
        // The BSDF, or its per-query table for `columns` (timed apart).
        let mut on = || -> Result<Option<PerQuery>, String> {
            if texture.is_none() {
                return Ok(None);
            }
            let t0 = thread_cpu_ns();
            let per = PerQuery::new(bsdf, n, &columns).map_err(|e| e.to_string())?;
            table += thread_cpu_ns() - t0;
            Ok(Some(per))
        };
        let wi = Vectors::from_flat(&self.wi).expect("3 floats a vertex");
        let light = Vectors::from_flat(&self.light).expect("3 floats a vertex");
        let per = on()?;
        let t0 = thread_cpu_ns();
        let mut out = SampleBuffers {
            wo: flat_mut(&mut self.wo),
            weight: flat_mut(&mut self.weight),
            pdf: &mut self.pdf,
            flags: &mut self.flags,
        };
        let q = Queries::directions(wi).keys(&self.keys);
        let answers: &dyn Bsdf = per.as_ref().map_or(bsdf, |p| p as &dyn Bsdf);
        answers
            .sample_into(&q, &mut |k, s| out.put(k, s))
            .map_err(e)?;
        let sample = thread_cpu_ns() - t0;
        drop(per);
        let per = on()?;
        let t0 = thread_cpu_ns();
        let mut f = flat_mut(&mut self.f);
        let light_pdf = &mut self.light_pdf;
        let q = Queries::pairs(wi, light).keys(&self.light_keys);
        let answers: &dyn Bsdf = per.as_ref().map_or(bsdf, |p| p as &dyn Bsdf);
        let evals = &mut |k, e: &Estimate| f.set(k, e.value.map(|v| v as f32));
        answers
            .eval_pdf_into(&q, evals, &mut |k, p| light_pdf[k] = p)
            .map_err(e)?;
        let light = thread_cpu_ns() - t0;
        drop(per);
        for (n, d) in ns.iter_mut().zip([table, sample, light]) {
            *n += d;
        }
        Ok(())
    }
}

/// Three floats a vertex, as the calls write them.
fn flat_mut(v: &mut [f32]) -> VectorsMut<'_> {
    VectorsMut::from_flat(v).expect("3 floats a vertex")
}

/// SplitMix64: the benchmark's own uniforms (light directions, keys).
fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

fn uniform(state: &mut u64) -> f64 {
    (splitmix(state) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The vertex estimator's scalar of vertex `k` of a batch run.
fn vertex_value(b: &Batch, k: usize, p_l: f64) -> f64 {
    let mean3 = |v: &[f32]| (v[3 * k] as f64 + v[3 * k + 1] as f64 + v[3 * k + 2] as f64) / 3.0;
    let mut x = 0.0;
    if b.flags[k] != 0 {
        let w = mean3(&b.weight);
        let d = [b.wo[3 * k], b.wo[3 * k + 1], b.wo[3 * k + 2]].map(|c| c as f64);
        let sun = if in_sun(d) {
            let delta = b.flags[k] & strata_bsdf::SampleFlags::DELTA != 0;
            let p_b = b.pdf[k] as f64;
            let mis = if delta {
                1.0
            } else {
                p_b * p_b / (p_b * p_b + p_l * p_l)
            };
            SUN_RADIANCE * mis
        } else {
            0.0
        };
        x += w * (1.0 + sun);
    }
    let f = mean3(&b.f);
    if f > 0.0 {
        let cos = (b.light[3 * k + 2] as f64).abs();
        let p_b = b.light_pdf[k] as f64;
        x += f * cos * SUN_RADIANCE / p_l * (p_l * p_l / (p_l * p_l + p_b * p_b));
    }
    x
}

/// Runs `batches` batches of `batch` vertices at the view `deg` on `bsdf`
/// (keys, light directions and texture values from `seed`), and returns
/// the estimate and the CPU time of the library's calls.
pub fn run(
    bsdf: &LayeredBsdf,
    deg: f64,
    batch: usize,
    batches: u32,
    seed: u64,
    mut texture: Option<&mut Texture>,
) -> Result<VertexRun, String> {
    let p_l = 1.0 / sun_solid_angle();
    let mut b = Batch::new(batch, view(deg));
    let mut rng = seed ^ 0x5eed_0f7e_27e5;
    let (mut sum, mut sum2, mut ns) = (0.0f64, 0.0f64, [0.0f64; 3]);
    // One batch first, neither timed nor counted: what the calls build on
    // first use, once per process (a rough coat's table of `R̄` for
    // per-query rows, the threads' buffers), is not a vertex's cost.
    for round in 0..=batches {
        for k in 0..batch {
            b.keys[k] = splitmix(&mut rng);
            b.light_keys[k] = splitmix(&mut rng);
            let d = sun_direction(uniform(&mut rng), uniform(&mut rng));
            for (c, x) in d.iter().enumerate() {
                b.light[3 * k + c] = *x as f32;
            }
        }
        if let Some(t) = texture.as_deref_mut() {
            t.draw(batch, &mut rng);
        }
        if round == 0 {
            b.run(bsdf, texture.as_deref(), &mut [0.0; 3])?;
            continue;
        }
        b.run(bsdf, texture.as_deref(), &mut ns)?;
        for k in 0..batch {
            let x = vertex_value(&b, k, p_l);
            sum += x;
            sum2 += x * x;
        }
    }
    let n = batch as f64 * batches as f64;
    let mean = sum / n;
    Ok(VertexRun {
        vertices: n as u64,
        mean,
        variance: ((sum2 - n * mean * mean) / (n - 1.0)).max(0.0),
        ns_per_vertex: ns.iter().sum::<f64>() / n,
        ns_per_call: ns.map(|t| t / n),
    })
}

/// The thread's CPU time in nanoseconds (wall time where the platform has
/// no thread clock).
pub fn thread_cpu_ns() -> f64 {
    #[cfg(unix)]
    {
        let mut t = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `t` is a valid, writable timespec; CLOCK_THREAD_CPUTIME_ID
        // is supported on Linux and the BSDs.
        if unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) } == 0 {
            return t.tv_sec as f64 * 1e9 + t.tv_nsec as f64;
        }
    }
    use std::sync::OnceLock;
    static START: OnceLock<std::time::Instant> = OnceLock::new();
    START
        .get_or_init(std::time::Instant::now)
        .elapsed()
        .as_nanos() as f64
}

/// The expected value of the vertex scalar at the view `deg`: the BSDF's
/// reflected albedo from the view (the sky) plus the sun's integral, by a
/// `m × m` product midpoint rule over the cone of `walks`-walk evals. For
/// tests: an answer of other calls than the vertex's (albedo and many-walk
/// eval), with its standard error.
pub fn expected(bsdf: &LayeredBsdf, deg: f64, walks: u64, m: usize) -> Result<(f64, f64), String> {
    let v = view(deg).map(|x| x as f32);
    let wi = Vec3::from_array(v);
    let a = bsdf.albedo(wi, walks).map_err(|e| e.to_string())?;
    let mean3 = |x: [f64; 3]| (x[0] + x[1] + x[2]) / 3.0;
    let (albedo, albedo_se) = (
        mean3(a.reflected.value),
        (a.reflected.stderr.iter().map(|s| s * s).sum::<f64>()).sqrt() / 3.0,
    );
    let omega = sun_solid_angle();
    let (mut sun, mut var) = (0.0, 0.0);
    let cell = omega / (m * m) as f64;
    let bsdf = bsdf.clone().samples(walks);
    for i in 0..m {
        for j in 0..m {
            let d = sun_direction((i as f64 + 0.5) / m as f64, (j as f64 + 0.5) / m as f64);
            let wo = Vec3::from_array(d.map(|x| x as f32));
            let e = bsdf.eval(wi, wo).map_err(|e| e.to_string())?;
            let c = d[2].abs() * cell * SUN_RADIANCE;
            sun += mean3(e.value) * c;
            var += (e.stderr.iter().map(|s| s * s).sum::<f64>() / 9.0) * c * c;
        }
    }
    Ok((albedo + sun, (albedo_se * albedo_se + var).sqrt()))
}

/// The configurations of the benchmark: pbrt-v4's layered six.
pub fn configs() -> Vec<Config> {
    pbrt::configs()
}
