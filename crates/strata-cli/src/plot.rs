//! PNG figures of BSDF lobes, rendered in memory with plotters and the bundled
//! DejaVu Sans font, then encoded as PNG (the caller writes the bytes
//! atomically).
//!
//! A figure shows one material in the plane of incidence (the x–z plane, with
//! `wi` at azimuth 0, so `wi.x >= 0`). Outgoing directions are given by a signed
//! angle `psi` in degrees, `wo = (sin psi, 0, cos psi)`: `|psi| < 90` is
//! reflection, `|psi| > 90` transmission, positive `psi` lies on the side of
//! `wi` (back-scattering) and the mirror direction of `wi` at `theta_i` is
//! `psi = -theta_i`.

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::sync::OnceLock;

/// The bundled font (DejaVu Sans, see `assets/DejaVuSans.LICENSE`).
static FONT_BYTES: &[u8] = include_bytes!("../../../assets/DejaVuSans.ttf");
/// The family name the font is registered under (plotters' default family).
const FONT: &str = "sans-serif";

/// Rec. 709 luminance weights: the plots show one number per direction.
pub const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Colours of successive lobes (Okabe–Ito, readable by colour-blind viewers).
const PALETTE: [RGBColor; 5] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
];

/// Registers the bundled font with plotters (once per process).
pub fn register_font() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES)
            .map_err(|_| "the bundled font assets/DejaVuSans.ttf is not a valid font".to_string())
    })
    .clone()
}

/// One estimated value of the lobe.
#[derive(Clone, Copy, Debug)]
pub struct LobePoint {
    /// Signed outgoing angle `psi` in degrees (see the module docs).
    pub psi_deg: f64,
    /// Luminance of f(wi, wo), 1/sr.
    pub f: f64,
    /// Standard error of `f` (an upper bound: see [`luminance_stderr`]).
    pub err: f64,
}

/// The lobe for one incidence angle.
#[derive(Clone, Debug)]
pub struct Lobe {
    /// Polar angle of `wi` in degrees (azimuth 0).
    pub theta_i_deg: f64,
    /// Points in increasing `psi`.
    pub points: Vec<LobePoint>,
}

/// One figure: a polar plot of f·cos θo and a log plot of f, side by side.
#[derive(Clone, Debug)]
pub struct LobeFigure {
    /// First title line.
    pub title: String,
    /// Second title line (smaller).
    pub subtitle: String,
    /// Show transmission (|psi| > 90) as well as reflection.
    pub transmissive: bool,
    /// The lobes, one per incidence angle.
    pub lobes: Vec<Lobe>,
}

/// Luminance of an RGB triple.
pub fn luminance(c: [f64; 3]) -> f64 {
    c.iter().zip(LUMINANCE).map(|(x, w)| x * w).sum()
}

/// A bound on the standard error of the luminance. The channels come from the
/// same walks and are correlated, so the exact error is not known from the
/// per-channel errors; `sd(Σ w_c X_c) <= Σ w_c sd(X_c)` bounds it.
pub fn luminance_stderr(e: [f64; 3]) -> f64 {
    luminance(e)
}

/// Figure size in pixels.
pub const SIZE: (u32, u32) = (1500, 680);

/// Renders `fig` and encodes it as PNG.
pub fn render_png(fig: &LobeFigure) -> Result<Vec<u8>, String> {
    register_font()?;
    let (w, h) = SIZE;
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        draw_figure(&root, fig).map_err(|e| format!("cannot draw the figure: {e}"))?;
        root.present()
            .map_err(|e| format!("cannot draw the figure: {e}"))?;
    }
    encode_png(&rgb, w, h)
}

/// Encodes 8-bit RGB pixels (`w` × `h`) as PNG.
pub fn encode_png(rgb: &[u8], w: u32, h: u32) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc
        .write_header()
        .map_err(|e| format!("cannot encode PNG: {e}"))?;
    writer
        .write_image_data(rgb)
        .map_err(|e| format!("cannot encode PNG: {e}"))?;
    writer
        .finish()
        .map_err(|e| format!("cannot encode PNG: {e}"))?;
    Ok(out)
}

type DrawResult<T> = Result<T, Box<dyn std::error::Error>>;

fn font(size: f64) -> TextStyle<'static> {
    (FONT, size).into_font().color(&BLACK)
}

fn draw_figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    fig: &LobeFigure,
) -> DrawResult<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(78);
    let (w, _) = head.dim_in_pixel();
    let center = Pos::new(HPos::Center, VPos::Top);
    head.draw_text(&fig.title, &font(26.0).pos(center), (w as i32 / 2, 10))?;
    head.draw_text(
        &fig.subtitle,
        &font(17.0).color(&RGBColor(70, 70, 70)).pos(center),
        (w as i32 / 2, 46),
    )?;
    let (left, right) = body.split_horizontally(w * 46 / 100);
    draw_polar(&left, fig)?;
    draw_log(&right, fig)?;
    Ok(())
}

/// A "nice" step (1, 2, 2.5 or 5 times a power of ten) near `x`.
fn nice_step(x: f64) -> f64 {
    let p = 10f64.powf(x.log10().floor());
    let m = x / p;
    let k = if m < 1.5 {
        1.0
    } else if m < 2.25 {
        2.0
    } else if m < 3.5 {
        2.5
    } else if m < 7.5 {
        5.0
    } else {
        10.0
    };
    k * p
}

/// Formats a ring radius or axis value compactly.
fn fmt_value(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (1e-3..1e4).contains(&v.abs()) {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.0e}")
    }
}

fn sides(fig: &LobeFigure) -> Vec<(f64, f64)> {
    if fig.transmissive {
        vec![(-90.0, 90.0), (90.0, 270.0)]
    } else {
        vec![(-90.0, 90.0)]
    }
}

/// The part of a lobe on one side: points with psi (mod 360) in `(lo, hi)`.
fn side_points(lobe: &Lobe, lo: f64, hi: f64) -> Vec<LobePoint> {
    let mut v: Vec<LobePoint> = lobe
        .points
        .iter()
        .map(|p| LobePoint {
            psi_deg: if p.psi_deg < lo {
                p.psi_deg + 360.0
            } else {
                p.psi_deg
            },
            ..*p
        })
        .filter(|p| p.psi_deg > lo && p.psi_deg < hi)
        .collect();
    v.sort_by(|a, b| a.psi_deg.total_cmp(&b.psi_deg));
    v
}

fn draw_polar<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, fig: &LobeFigure) -> DrawResult<()>
where
    DB::ErrorType: 'static,
{
    let area = area.titled(
        "f·|cos θo| in the plane of incidence (linear, 1/sr)",
        font(19.0),
    )?;
    let area = area.margin(10, 10, 20, 20);
    let (pw, ph) = area.dim_in_pixel();
    let (pw, ph) = (pw as f64, ph as f64);

    let r_max = fig
        .lobes
        .iter()
        .flat_map(|l| l.points.iter())
        .map(|p| p.f * p.psi_deg.to_radians().cos().abs())
        .filter(|r| r.is_finite())
        .fold(0.0f64, f64::max);
    let r_max = if r_max > 0.0 { r_max } else { 1.0 };
    let step = nice_step(r_max / 4.0);
    let rings: Vec<f64> = (1..=12)
        .map(|k| k as f64 * step)
        .take_while(|&r| r <= r_max * 1.0001 + step * 0.5)
        .collect();
    let r_outer = rings.last().copied().unwrap_or(r_max).max(r_max);
    let r_pad = r_outer * 1.16;
    // Data extent (before fitting to the pixel aspect ratio).
    let (y_lo, y_hi) = if fig.transmissive {
        (-r_pad, r_pad)
    } else {
        (-0.1 * r_pad, r_pad)
    };
    let s = (pw / (2.0 * r_pad)).min(ph / (y_hi - y_lo));
    let (hx, hy) = (pw / (2.0 * s), ph / (2.0 * s));
    let yc = 0.5 * (y_lo + y_hi);
    let mut chart = ChartBuilder::on(&area).build_cartesian_2d(-hx..hx, (yc - hy)..(yc + hy))?;

    let grid = RGBColor(200, 200, 200);
    let arc = |r: f64, lo: f64, hi: f64| {
        let n = 180;
        (0..=n).map(move |k| {
            let t = (lo + (hi - lo) * k as f64 / n as f64).to_radians();
            (r * t.sin(), r * t.cos())
        })
    };
    let (a_lo, a_hi) = if fig.transmissive {
        (-180.0, 180.0)
    } else {
        (-90.0, 90.0)
    };
    for &r in &rings {
        chart.draw_series(LineSeries::new(arc(r, a_lo, a_hi), grid.stroke_width(1)))?;
        // Ring labels along the surface line (where every lobe is near zero),
        // ending at their ring.
        chart.draw_series(std::iter::once(Text::new(
            fmt_value(r),
            (r, 0.0),
            font(14.0)
                .color(&RGBColor(90, 90, 90))
                .pos(Pos::new(HPos::Right, VPos::Top)),
        )))?;
    }
    let mut a = a_lo;
    while a <= a_hi + 1e-9 {
        let t = f64::to_radians(a);
        chart.draw_series(LineSeries::new(
            [(0.0, 0.0), (r_outer * t.sin(), r_outer * t.cos())],
            grid.stroke_width(1),
        ))?;
        if !(fig.transmissive && a == -180.0) {
            let rl = r_outer * 1.07;
            let label = if a == 180.0 {
                "180°".to_string()
            } else {
                format!("{a:.0}°")
            };
            // ±90° continue the surface line, outside it.
            let (h, at) = if a == -90.0 {
                (HPos::Right, (-r_outer * 1.03, 0.0))
            } else if a == 90.0 {
                (HPos::Left, (r_outer * 1.03, 0.0))
            } else {
                (HPos::Center, (rl * t.sin(), rl * t.cos()))
            };
            chart.draw_series(std::iter::once(Text::new(
                label,
                at,
                font(14.0).pos(Pos::new(h, VPos::Center)),
            )))?;
        }
        a += 30.0;
    }
    // The surface.
    chart.draw_series(LineSeries::new(
        [(-r_outer * 1.01, 0.0), (r_outer * 1.01, 0.0)],
        BLACK.stroke_width(2),
    ))?;
    let side_label = |text: &'static str, v: VPos| {
        Text::new(
            text,
            (-r_outer * 0.99, 0.0),
            font(14.0).pos(Pos::new(HPos::Left, v)),
        )
    };
    if fig.transmissive {
        chart.draw_series([
            side_label("reflection (above)", VPos::Bottom),
            side_label("transmission (below)", VPos::Top),
        ])?;
    } else {
        chart.draw_series([side_label("surface", VPos::Bottom)])?;
    }

    for (j, lobe) in fig.lobes.iter().enumerate() {
        let color = PALETTE[j % PALETTE.len()];
        // The incident direction, dashed.
        let t = lobe.theta_i_deg.to_radians();
        chart.draw_series(DashedLineSeries::new(
            [(0.0, 0.0), (r_outer * t.sin(), r_outer * t.cos())],
            8,
            6,
            color.stroke_width(2),
        ))?;
        let mut first = true;
        for (lo, hi) in sides(fig) {
            let pts = side_points(lobe, lo, hi);
            let series = chart.draw_series(LineSeries::new(
                pts.iter().map(|p| {
                    let t = p.psi_deg.to_radians();
                    let r = (p.f * t.cos().abs()).max(0.0);
                    (r * t.sin(), r * t.cos())
                }),
                color.stroke_width(3),
            ))?;
            if first {
                series
                    .label(format!("θi = {:.0}°", lobe.theta_i_deg))
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3))
                    });
                first = false;
            }
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .label_font(font(15.0))
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(160, 160, 160))
        .draw()?;
    chart.draw_series(std::iter::once(Text::new(
        "dashed: incident direction wi",
        (hx, yc + hy),
        font(14.0)
            .color(&RGBColor(90, 90, 90))
            .pos(Pos::new(HPos::Right, VPos::Top)),
    )))?;
    Ok(())
}

fn draw_log<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, fig: &LobeFigure) -> DrawResult<()>
where
    DB::ErrorType: 'static,
{
    let positive = fig
        .lobes
        .iter()
        .flat_map(|l| l.points.iter())
        .filter(|p| p.f > 0.0 && p.f.is_finite());
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for p in positive {
        lo = lo.min(p.f);
        hi = hi.max(p.f + p.err);
    }
    if hi <= 0.0 {
        (lo, hi) = (1e-3, 1.0);
    }
    // Headroom above the peak for the legend; at most five decades below it
    // (lower values are noise or zeros).
    let y_hi = hi * 40.0;
    let y_lo = 10f64.powf((lo.max(hi * 1e-5) / 1.5).log10().floor());
    let (x_lo, x_hi) = if fig.transmissive {
        (-180.0, 180.0)
    } else {
        (-90.0, 90.0)
    };
    let x_range = Degrees { lo: x_lo, hi: x_hi };
    let mut chart = ChartBuilder::on(area)
        .caption(
            "f in the plane of incidence (log scale, ±1 standard error)",
            font(19.0),
        )
        .margin_top(6)
        .margin_right(30)
        .margin_bottom(10)
        .x_label_area_size(56)
        .y_label_area_size(84)
        .build_cartesian_2d(x_range, (y_lo..y_hi).log_scale())?;
    chart
        .configure_mesh()
        .x_label_formatter(&|x| format!("{x:.0}°"))
        .y_label_formatter(&|y| fmt_value(*y))
        .x_desc("outgoing angle θo in the plane of incidence (+ = side of wi, − = mirror side)")
        .y_desc("f (luminance, 1/sr)")
        .axis_desc_style(font(16.0))
        .label_style(font(14.0))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .draw()?;
    if fig.transmissive {
        for x in [-90.0, 90.0] {
            chart.draw_series(DashedLineSeries::new(
                [(x, y_lo), (x, y_hi)],
                6,
                5,
                BLACK.stroke_width(1),
            ))?;
        }
        let bottom = y_lo * 1.2;
        for (x, label) in [
            (-135.0, "transmission"),
            (0.0, "reflection"),
            (135.0, "transmission"),
        ] {
            chart.draw_series(std::iter::once(Text::new(
                label,
                (x, bottom),
                font(15.0)
                    .color(&RGBColor(90, 90, 90))
                    .pos(Pos::new(HPos::Center, VPos::Bottom)),
            )))?;
        }
    }
    for (j, lobe) in fig.lobes.iter().enumerate() {
        let color = PALETTE[j % PALETTE.len()];
        let mut pts: Vec<LobePoint> = lobe.points.clone();
        pts.sort_by(|a, b| a.psi_deg.total_cmp(&b.psi_deg));
        // Error bars.
        chart.draw_series(pts.iter().filter(|p| p.f > 0.0).map(|p| {
            let a = (p.f - p.err).max(y_lo);
            let b = (p.f + p.err).min(y_hi);
            PathElement::new(vec![(p.psi_deg, a), (p.psi_deg, b)], color.mix(0.45))
        }))?;
        // The curve, broken where f is zero (nothing to show on a log axis)
        // and across grazing (|psi| = 90).
        let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
        let mut prev_side = None;
        for p in &pts {
            let side = p.psi_deg.abs() < 90.0;
            let keep = p.f > 0.0 && p.f.is_finite();
            let cur = runs.last_mut().expect("runs is never empty");
            if (!keep || prev_side.is_some_and(|s| s != side)) && !cur.is_empty() {
                runs.push(Vec::new());
            }
            if keep {
                runs.last_mut()
                    .expect("runs is never empty")
                    .push((p.psi_deg, p.f.max(y_lo)));
            }
            prev_side = Some(side);
        }
        let mut first = true;
        for run in runs.into_iter().filter(|r| !r.is_empty()) {
            let s = chart.draw_series(LineSeries::new(run, color.stroke_width(2)))?;
            if first {
                s.label(format!(
                    "θi = {:.0}° (mirror at θo = {:.0}°)",
                    lobe.theta_i_deg,
                    0.0 - lobe.theta_i_deg
                ))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3))
                });
                first = false;
            }
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font(font(15.0))
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(160, 160, 160))
        .draw()?;
    Ok(())
}

/// An axis in degrees with labelled grid lines every 30° and light ones every
/// 10° (plotters' own f64 axis only picks 1-2-5 steps).
struct Degrees {
    lo: f64,
    hi: f64,
}

impl Ranged for Degrees {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let t = (v - self.lo) / (self.hi - self.lo);
        limit.0 + (t * f64::from(limit.1 - limit.0)).round() as i32
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        let step = if hint.weight().allow_light_points() {
            10.0
        } else {
            30.0
        };
        let first = (self.lo / step).ceil() as i32;
        let last = (self.hi / step).floor() as i32;
        (first..=last).map(|k| f64::from(k) * step).collect()
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}
