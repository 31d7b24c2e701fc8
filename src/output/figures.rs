//! PNG figures of a run: the spatio-temporal porosity of seed 000 fig. 3, the pressure-drop
//! trace, plug statistics along the tube with quartile bands (seed 000 figs. 10–12), and
//! characteristic curves of sweeps. Drawn with plotters' bitmap backend; the font (DejaVu
//! Sans, `assets/fonts/`, Bitstream Vera licence) is compiled in so figures need nothing
//! from the machine.

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;

use super::OutputError;
use crate::analysis::plugs::PlugObservation;
use crate::Real;

static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

fn register_font() {
    REGISTER.call_once(|| {
        // The bytes are a valid TrueType font compiled into the binary.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// One curve of a panel.
#[derive(Debug, Clone)]
pub struct Curve {
    /// Legend text.
    pub label: String,
    /// (x, y) points.
    pub points: Vec<(Real, Real)>,
    /// Draw markers only (measurements), not a line.
    pub markers: bool,
    /// Optional band (x, lo, hi) shaded behind the curve.
    pub band: Vec<(Real, Real, Real)>,
}

impl Curve {
    /// A plain line.
    pub fn line(label: impl Into<String>, points: Vec<(Real, Real)>) -> Self {
        Self {
            label: label.into(),
            points,
            markers: false,
            band: Vec::new(),
        }
    }
}

/// One panel: title, axis labels, curves.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Title above the panel.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// The curves.
    pub curves: Vec<Curve>,
}

const COLOURS: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];

fn range(values: impl Iterator<Item = Real>) -> (Real, Real) {
    let (mut lo, mut hi) = (Real::INFINITY, Real::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-12 * (1.0 + lo.abs()) {
        return (lo - 0.5 * (1.0 + lo.abs()), hi + 0.5 * (1.0 + hi.abs()));
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// Draw panels side by side (one row) into a PNG.
pub fn panels(path: &Path, panels: &[Panel], width: u32, height: u32) -> Result<(), OutputError> {
    register_font();
    let err = |e: &dyn std::fmt::Display| OutputError::new(path.display(), e);
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let areas = root.split_evenly((1, panels.len().max(1)));
    for (panel, area) in panels.iter().zip(areas.iter()) {
        let xs = panel.curves.iter().flat_map(|c| {
            c.points
                .iter()
                .map(|p| p.0)
                .chain(c.band.iter().map(|b| b.0))
        });
        let ys = panel.curves.iter().flat_map(|c| {
            c.points
                .iter()
                .map(|p| p.1)
                .chain(c.band.iter().flat_map(|b| [b.1, b.2]))
        });
        let (x0, x1) = range(xs);
        let (y0, y1) = range(ys);
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc(panel.x_label.as_str())
            .y_desc(panel.y_label.as_str())
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(|e| err(&e))?;
        for (k, c) in panel.curves.iter().enumerate() {
            let colour = COLOURS[k % COLOURS.len()];
            if !c.band.is_empty() {
                let mut poly: Vec<(Real, Real)> = c.band.iter().map(|b| (b.0, b.1)).collect();
                poly.extend(c.band.iter().rev().map(|b| (b.0, b.2)));
                chart
                    .draw_series(std::iter::once(Polygon::new(
                        poly,
                        colour.mix(0.2).filled(),
                    )))
                    .map_err(|e| err(&e))?;
            }
            let pts: Vec<(Real, Real)> = c
                .points
                .iter()
                .copied()
                .filter(|p| p.0.is_finite() && p.1.is_finite())
                .collect();
            let drawn = if c.markers {
                chart
                    .draw_series(pts.iter().map(|p| Circle::new(*p, 4, colour.filled())))
                    .map_err(|e| err(&e))?
            } else {
                chart
                    .draw_series(LineSeries::new(pts, colour.stroke_width(2)))
                    .map_err(|e| err(&e))?
            };
            if !c.label.is_empty() {
                drawn.label(c.label.as_str()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], colour.stroke_width(2))
                });
            }
        }
        if panel.curves.iter().any(|c| !c.label.is_empty()) {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .label_font(("sans-serif", 13))
                .draw()
                .map_err(|e| err(&e))?;
        }
    }
    root.present().map_err(|e| err(&e))
}

/// A field over time and position along the tube (seed 000 fig. 3): one cell per sample
/// (`times`, s) and position (`z`, m, equally spaced), grey from `range.0` (black) to
/// `range.1` (white), with axes and a colour bar labelled `what`.
pub fn spacetime(
    path: &Path,
    what: &str,
    times: &[Real],
    z: &[Real],
    rows: &[Vec<Real>],
    range: (Real, Real),
) -> Result<(), OutputError> {
    register_font();
    let err = |e: &dyn std::fmt::Display| OutputError::new(path.display(), e);
    if times.is_empty() || z.is_empty() || rows.len() != times.len() {
        return Err(err(&format!(
            "{} samples of {} rows and {} positions: nothing consistent to draw",
            times.len(),
            rows.len(),
            z.len()
        )));
    }
    // Cell edges half-way between samples (and positions); the ends half a step out.
    let edges = |c: &[Real]| -> Vec<Real> {
        let step = if c.len() > 1 { c[1] - c[0] } else { 1.0 };
        let mut e = vec![c[0] - 0.5 * step];
        e.extend(c.windows(2).map(|w| 0.5 * (w[0] + w[1])));
        e.push(c[c.len() - 1] + 0.5 * step);
        e
    };
    let (te, ze) = (edges(times), edges(z));
    let grey = |v: Real| {
        let g = (((v - range.0) / (range.1 - range.0)).clamp(0.0, 1.0) * 255.0).round() as u8;
        RGBColor(g, g, g)
    };
    let width = (times.len() as u32 + 220).clamp(800, 2400);
    let root = BitMapBackend::new(path, (width, 520)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (main, bar) = root.split_horizontally(width - 120);
    let mut chart = ChartBuilder::on(&main)
        .caption(
            format!("{what} over time along the tube"),
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(te[0]..te[te.len() - 1], ze[0]..ze[ze.len() - 1])
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("time t (s)")
        .y_desc("position along the tube (m)")
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(|e| err(&e))?;
    let ze = &ze;
    chart
        .draw_series(rows.iter().enumerate().flat_map(|(i, row)| {
            let (t0, t1) = (te[i], te[i + 1]);
            row.iter().enumerate().map(move |(k, &v)| {
                Rectangle::new([(t0, ze[k]), (t1, ze[k + 1])], grey(v).filled())
            })
        }))
        .map_err(|e| err(&e))?;
    let mut scale = ChartBuilder::on(&bar)
        .margin_top(40)
        .margin_bottom(50)
        .margin_right(10)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..1.0, range.0..range.1)
        .map_err(|e| err(&e))?;
    scale
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(what)
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(|e| err(&e))?;
    let n = 100;
    scale
        .draw_series((0..n).map(|k| {
            let (a, b) = (k as Real / n as Real, (k + 1) as Real / n as Real);
            let (lo, hi) = (
                range.0 + a * (range.1 - range.0),
                range.0 + b * (range.1 - range.0),
            );
            Rectangle::new([(0.0, lo), (1.0, hi)], grey(0.5 * (lo + hi)).filled())
        }))
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}

/// Quartiles (q1, median, q3) of a sample; None when empty.
pub fn quartiles(mut v: Vec<Real>) -> Option<(Real, Real, Real)> {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return None;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let q = |p: Real| {
        let x = p * (v.len() - 1) as Real;
        let (i, f) = (x.floor() as usize, x - x.floor());
        if i + 1 < v.len() {
            v[i] * (1.0 - f) + v[i + 1] * f
        } else {
            v[i]
        }
    };
    Some((q(0.25), q(0.5), q(0.75)))
}

/// Plug statistics along the tube (seed 000 figs. 10–12): plug rate, minimum porosity,
/// velocity (tracked) and length against height, medians with quartile bands, in bins of
/// `bin` m.
pub fn plug_statistics(
    path: &Path,
    plugs: &[PlugObservation],
    tube_length: Real,
    span: Real,
    bin: Real,
) -> Result<(), OutputError> {
    let nbins = (tube_length / bin).ceil().max(1.0) as usize;
    let mut panels_out = Vec::new();
    // Rate: distinct tracks whose centre visited each bin, per second.
    let mut rate = Vec::new();
    for b in 0..nbins {
        let (lo, hi) = (b as Real * bin, (b + 1) as Real * bin);
        let tracks: std::collections::BTreeSet<u64> = plugs
            .iter()
            .filter(|p| p.centre >= lo && p.centre < hi)
            .map(|p| p.track)
            .collect();
        rate.push((0.5 * (lo + hi), tracks.len() as Real / span.max(1e-12)));
    }
    panels_out.push(Panel {
        title: "plug rate".into(),
        x_label: "height z (m)".into(),
        y_label: "plugs per second".into(),
        curves: vec![Curve::line("", rate)],
    });
    type Pick = fn(&PlugObservation) -> Option<Real>;
    /// Panel title, unit, and its curves (label, value per plug).
    type Stat<'a> = (&'a str, &'a str, &'a [(&'a str, Pick)]);
    let stats: [Stat; 3] = [
        (
            "minimum porosity",
            "porosity",
            &[("median, quartiles", |p| Some(p.min_porosity))],
        ),
        (
            "plug velocity",
            "m/s",
            &[
                ("max granular (seed fig. 11)", |p| Some(p.max_velocity)),
                ("tracked plug", |p| p.velocity),
            ],
        ),
        (
            "plug length",
            "m",
            &[("median, quartiles", |p| Some(p.length))],
        ),
    ];
    for (title, unit, picks) in stats {
        let mut curves = Vec::new();
        for (label, pick) in picks {
            let mut med = Vec::new();
            let mut band = Vec::new();
            for b in 0..nbins {
                let (lo, hi) = (b as Real * bin, (b + 1) as Real * bin);
                let v: Vec<Real> = plugs
                    .iter()
                    .filter(|p| p.centre >= lo && p.centre < hi)
                    .filter_map(pick)
                    .collect();
                if let Some((q1, q2, q3)) = quartiles(v) {
                    let z = 0.5 * (lo + hi);
                    med.push((z, q2));
                    band.push((z, q1, q3));
                }
            }
            curves.push(Curve {
                label: (*label).into(),
                points: med,
                markers: false,
                band,
            });
        }
        panels_out.push(Panel {
            title: title.into(),
            x_label: "height z (m)".into(),
            y_label: unit.into(),
            curves,
        });
    }
    panels(path, &panels_out, 1600, 420)
}

/// Profiles averaged over plugs: along the tube around the plug centre, radially in the
/// plug, and across the tube (inside plugs and between them).
pub fn profiles(
    path: &Path,
    r: &crate::analysis::profiles::ProfileResult,
) -> Result<(), OutputError> {
    let xy = |x: &[Real], y: &[Real]| -> Vec<(Real, Real)> {
        x.iter().zip(y).map(|(a, b)| (*a, *b)).collect()
    };
    let xi_cm: Vec<Real> = r.xi.iter().map(|x| x * 100.0).collect();
    let panels_out = [
        Panel {
            title: format!("along the plug ({} plug frames)", r.plugs_used),
            x_label: "distance from plug centre (cm)".into(),
            y_label: "porosity".into(),
            curves: vec![Curve::line("porosity", xy(&xi_cm, &r.porosity))],
        },
        Panel {
            title: "granular velocity and temperature".into(),
            x_label: "distance from plug centre (cm)".into(),
            y_label: "m/s, (m/s)² × 100".into(),
            curves: vec![
                Curve::line("axial velocity", xy(&xi_cm, &r.velocity)),
                Curve::line(
                    "temperature × 100",
                    xy(
                        &xi_cm,
                        &r.temperature.iter().map(|t| t * 100.0).collect::<Vec<_>>(),
                    ),
                ),
            ],
        },
        Panel {
            title: "wall normal stress, drag, contact force".into(),
            x_label: "distance from plug centre (cm)".into(),
            y_label: "Pa, N/m³ / 100".into(),
            curves: vec![
                Curve::line("wall normal stress", xy(&xi_cm, &r.wall_stress)),
                Curve::line(
                    "axial drag / 100",
                    xy(
                        &xi_cm,
                        &r.drag.iter().map(|d| d / 100.0).collect::<Vec<_>>(),
                    ),
                ),
                Curve::line(
                    "axial contact force / 100",
                    xy(
                        &xi_cm,
                        &r.particle_force
                            .iter()
                            .map(|d| d / 100.0)
                            .collect::<Vec<_>>(),
                    ),
                ),
            ],
        },
        Panel {
            title: "radial (section 1.5 d)".into(),
            x_label: "r / d".into(),
            y_label: "porosity".into(),
            curves: vec![Curve::line("", xy(&r.ring_r_over_d, &r.ring_porosity))],
        },
        Panel {
            title: "across the tube".into(),
            x_label: "height / d".into(),
            y_label: "porosity".into(),
            curves: vec![
                Curve::line("in plugs", xy(&r.layer_h_over_d, &r.layer_porosity_plug)),
                Curve::line(
                    "between plugs",
                    xy(&r.layer_h_over_d, &r.layer_porosity_gap),
                ),
            ],
        },
    ];
    panels(path, &panels_out, 2000, 420)
}
