//! SVG plots with plotters: stacked line panels (time series, correlation
//! stems with confidence bands) and 2-D polygon partitions.

use anyhow::anyhow;
use plotters::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

/// Where a TrueType font is looked for (Debian's `fonts-dejavu-core` first).
const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
];

/// Registers a font with plotters once (SVG text needs font metrics).
fn ensure_font() -> anyhow::Result<()> {
    static FONT: OnceLock<Result<(), String>> = OnceLock::new();
    FONT.get_or_init(|| {
        let path = FONT_PATHS
            .iter()
            .find(|p| Path::new(p).exists())
            .ok_or_else(|| {
                "no TrueType font found for the plots; install Debian's fonts-dejavu-core"
                    .to_string()
            })?;
        let bytes = std::fs::read(path).map_err(|e| format!("{path}: {e}"))?;
        let leaked: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", FontStyle::Normal, leaked)
            .map_err(|_| format!("{path}: not a usable TrueType font"))
    })
    .clone()
    .map_err(|e| anyhow!(e))
}

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SeriesKind {
    /// A solid line.
    Line,
    /// A dashed line (references, predictions).
    Dashed,
    /// Vertical stems from zero (correlations).
    Stems,
}

/// One named series of a panel.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// The points.
    pub points: Vec<(f64, f64)>,
    /// How it is drawn.
    pub kind: SeriesKind,
}

impl Series {
    /// A solid line.
    pub fn line(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series {
            name: name.into(),
            points,
            kind: SeriesKind::Line,
        }
    }
    /// A dashed line.
    pub fn dashed(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series {
            name: name.into(),
            points,
            kind: SeriesKind::Dashed,
        }
    }
    /// Stems from zero.
    pub fn stems(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series {
            name: name.into(),
            points,
            kind: SeriesKind::Stems,
        }
    }
}

/// One panel (axes) of a figure.
#[derive(Clone, Debug, Default)]
pub struct Panel {
    /// Panel title.
    pub title: String,
    /// Horizontal axis label.
    pub x_label: String,
    /// Vertical axis label.
    pub y_label: String,
    /// The series.
    pub series: Vec<Series>,
    /// Horizontal lines (value, legend), e.g. confidence bands or limits.
    pub hlines: Vec<(f64, String)>,
}

fn color(i: usize) -> RGBColor {
    const C: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
    ];
    C[i % C.len()]
}

fn range_of(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-12 * (1.0 + lo.abs()) {
        return (lo - 0.5 - 0.1 * lo.abs(), hi + 0.5 + 0.1 * hi.abs());
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

fn plot_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("drawing the plot: {e:?}")
}

/// Draws panels stacked vertically into one SVG file.
pub fn panels_svg(path: &Path, title: &str, panels: &[Panel]) -> anyhow::Result<()> {
    ensure_font()?;
    let height = 60 + 260 * panels.len().max(1) as u32;
    let root = SVGBackend::new(path, (900, height)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let root = root.titled(title, ("sans-serif", 22)).map_err(plot_err)?;
    let areas = root.split_evenly((panels.len().max(1), 1));
    for (panel, area) in panels.iter().zip(areas.iter()) {
        let xs = panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.0));
        let (x0, x1) = range_of(xs);
        let mut ys: Vec<f64> = panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .collect();
        ys.extend(panel.hlines.iter().map(|h| h.0));
        if panel.series.iter().any(|s| s.kind == SeriesKind::Stems) {
            ys.push(0.0);
        }
        let (y0, y1) = range_of(ys.into_iter());
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc(panel.x_label.as_str())
            .y_desc(panel.y_label.as_str())
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(plot_err)?;
        for (i, s) in panel.series.iter().enumerate() {
            let c = color(i);
            let style =
                ShapeStyle::from(&c).stroke_width(if s.kind == SeriesKind::Line { 2 } else { 1 });
            let pts: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .filter(|p| p.0.is_finite() && p.1.is_finite())
                .collect();
            match s.kind {
                SeriesKind::Line => {
                    chart
                        .draw_series(LineSeries::new(pts, style))
                        .map_err(plot_err)?
                        .label(s.name.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], c));
                }
                SeriesKind::Dashed => {
                    chart
                        .draw_series(DashedLineSeries::new(pts, 6, 4, style))
                        .map_err(plot_err)?
                        .label(s.name.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], c));
                }
                SeriesKind::Stems => {
                    chart
                        .draw_series(
                            pts.iter()
                                .map(|&(x, y)| PathElement::new(vec![(x, 0.0), (x, y)], style)),
                        )
                        .map_err(plot_err)?
                        .label(s.name.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], c));
                    chart
                        .draw_series(pts.iter().map(|&(x, y)| Circle::new((x, y), 2, c.filled())))
                        .map_err(plot_err)?;
                }
            }
        }
        for (k, (v, name)) in panel.hlines.iter().enumerate() {
            let c = RGBColor(90, 90, 90);
            let series = chart
                .draw_series(DashedLineSeries::new(
                    vec![(x0, *v), (x1, *v)],
                    4,
                    4,
                    ShapeStyle::from(&c),
                ))
                .map_err(plot_err)?;
            // One legend entry per distinct name (a band's two lines share one).
            if !name.is_empty() && panel.hlines[..k].iter().all(|h| &h.1 != name) {
                series
                    .label(name.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], c));
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(plot_err)?;
    }
    root.present().map_err(plot_err)?;
    Ok(())
}

/// A filled polygon of a 2-D partition plot.
#[derive(Clone, Debug)]
pub struct Polygon {
    /// Vertices in order (closed implicitly).
    pub vertices: Vec<(f64, f64)>,
    /// Colour group (e.g. the index of a distinct control law).
    pub group: usize,
}

/// Draws a 2-D partition (e.g. a slice of the explicit-MPC regions).
pub fn partition_svg(
    path: &Path,
    title: &str,
    labels: (&str, &str),
    x_range: (f64, f64),
    y_range: (f64, f64),
    polygons: &[Polygon],
) -> anyhow::Result<()> {
    ensure_font()?;
    let root = SVGBackend::new(path, (760, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x_range.0..x_range.1, y_range.0..y_range.1)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc(labels.0)
        .y_desc(labels.1)
        .draw()
        .map_err(plot_err)?;
    chart
        .draw_series(polygons.iter().filter(|p| p.vertices.len() >= 3).map(|p| {
            let c = color(p.group);
            plotters::element::Polygon::new(p.vertices.clone(), c.mix(0.55).filled())
        }))
        .map_err(plot_err)?;
    chart
        .draw_series(polygons.iter().filter(|p| p.vertices.len() >= 3).map(|p| {
            let mut v = p.vertices.clone();
            v.push(v[0]);
            PathElement::new(v, BLACK.stroke_width(1))
        }))
        .map_err(plot_err)?;
    root.present().map_err(plot_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_svg_files() {
        let dir = std::env::temp_dir().join(format!("kestrel-plot-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let t: Vec<f64> = (0..100).map(|k| k as f64 * 0.02).collect();
        let panel = Panel {
            title: "p".into(),
            x_label: "time [s]".into(),
            y_label: "rad/s".into(),
            series: vec![
                Series::line("measured", t.iter().map(|&x| (x, x.sin())).collect()),
                Series::dashed("simulated", t.iter().map(|&x| (x, 0.9 * x.sin())).collect()),
            ],
            hlines: vec![(0.5, "limit".into()), (-0.5, "limit".into())],
        };
        let stems = Panel {
            title: "residual autocorrelation".into(),
            series: vec![Series::stems(
                "r",
                (-5..=5).map(|k| (k as f64, 0.1 * k as f64)).collect(),
            )],
            ..Default::default()
        };
        let p = dir.join("lines.svg");
        panels_svg(&p, "test", &[panel, stems]).unwrap();
        let svg = std::fs::read_to_string(&p).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("measured") && svg.contains("<polyline"));
        let q = dir.join("part.svg");
        let polys = vec![
            Polygon {
                vertices: vec![(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)],
                group: 0,
            },
            Polygon {
                vertices: vec![(1.0, 0.0), (1.0, 1.0), (0.0, 1.0)],
                group: 1,
            },
        ];
        partition_svg(
            &q,
            "partition",
            ("x1", "x2"),
            (0.0, 1.0),
            (0.0, 1.0),
            &polys,
        )
        .unwrap();
        assert!(std::fs::read_to_string(&q).unwrap().contains("<polygon"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
