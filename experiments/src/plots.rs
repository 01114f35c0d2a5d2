//! Figures drawn with plotters, each written as PNG and SVG.
//!
//! Text uses DejaVu Sans, embedded in the binary (`experiments/assets/`, Bitstream Vera license)
//! and registered with plotters' `ab_glyph` font loader, so no system font library is
//! needed.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{FontStyle, register_font};

use crate::ExperimentError;
use crate::atomic::write_atomic;

/// DejaVu Sans (see `experiments/assets/DejaVuSans-LICENSE.txt`).
static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// Registers the embedded font as plotters' `sans-serif` family (once per process).
fn ensure_font() -> Result<(), String> {
    static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            register_font("sans-serif", FontStyle::Normal, FONT)
                .map_err(|_| "the embedded font is invalid".to_string())
        })
        .clone()
}

/// Twenty distinct colours (matplotlib's `tab10`, then the light half of `tab20`), assigned
/// to series in order.
pub const PALETTE: [RGBColor; 20] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(174, 199, 232),
    RGBColor(255, 187, 120),
    RGBColor(152, 223, 138),
    RGBColor(255, 152, 150),
    RGBColor(197, 176, 213),
    RGBColor(196, 156, 148),
    RGBColor(247, 182, 210),
    RGBColor(199, 199, 199),
    RGBColor(219, 219, 141),
    RGBColor(158, 218, 229),
];

/// The colour of series number `i` (the palette repeats after twenty).
pub fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// One line of a panel.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Line colour.
    pub color: RGBColor,
    /// `(x, y)` points in x order. On a log axis, points with y ≤ 0 are left out.
    pub points: Vec<(f64, f64)>,
}

/// Scale of a panel's y axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Linear, starting at 0 for non-negative data (default).
    #[default]
    Linear,
    /// Base-10 logarithmic.
    Log,
}

/// One chart: axes, series and a legend.
#[derive(Debug, Clone, Default)]
pub struct Panel {
    /// Title above the chart.
    pub title: String,
    /// X axis label, with its unit.
    pub x_label: String,
    /// Y axis label, with its unit.
    pub y_label: String,
    /// Y axis scale (default linear).
    pub y_scale: Scale,
    /// The lines.
    pub series: Vec<Series>,
    /// X range; `None` (default) fits the data.
    pub x_range: Option<(f64, f64)>,
    /// A horizontal reference line `(y, legend text)`, drawn dashed in black (default none).
    pub reference: Option<(f64, String)>,
    /// Lower end of the y axis; smaller values are drawn on it. `None` (default) fits the data.
    pub y_min: Option<f64>,
}

/// A figure: panels side by side under a title.
#[derive(Debug, Clone)]
pub struct Figure {
    /// Title of the whole figure.
    pub title: String,
    /// Panels, left to right.
    pub panels: Vec<Panel>,
    /// Size in pixels (default 1200 × 700 per panel row via [`Figure::new`]).
    pub size: (u32, u32),
}

impl Figure {
    /// A figure of `panels` side by side, 1200 × 700 pixels for one panel and 800 pixels
    /// wider for each further panel.
    pub fn new(title: impl Into<String>, panels: Vec<Panel>) -> Self {
        let width = 1200 + 800 * (panels.len().max(1) as u32 - 1);
        Self {
            title: title.into(),
            panels,
            size: (width, 700),
        }
    }
}

fn plot_err(path: &Path, e: impl std::fmt::Display) -> ExperimentError {
    ExperimentError::Plot {
        path: path.display().to_string(),
        reason: e.to_string(),
    }
}

/// Draws `figure` as `<dir>/<name>.png` and `<dir>/<name>.svg`. Each file is drawn to a
/// temporary file in `dir` and renamed into place, so an interrupted run never leaves a
/// half-written figure. Returns the two paths.
pub fn draw(figure: &Figure, dir: &Path, name: &str) -> Result<Vec<PathBuf>, ExperimentError> {
    let png = dir.join(format!("{name}.png"));
    let svg = dir.join(format!("{name}.svg"));
    ensure_font().map_err(|e| plot_err(&png, e))?;

    // The PNG encoder picks the format from the extension, so the temporary name ends in .png.
    let tmp_png = dir.join(format!(".{name}.tmp-{}.png", std::process::id()));
    let drawn = (|| {
        let root = BitMapBackend::new(&tmp_png, figure.size).into_drawing_area();
        render(&root, figure)?;
        root.present().map_err(|e| e.to_string())
    })();
    if let Err(e) = drawn {
        let _ = std::fs::remove_file(&tmp_png);
        return Err(plot_err(&png, e));
    }
    std::fs::rename(&tmp_png, &png).map_err(|source| {
        let _ = std::fs::remove_file(&tmp_png);
        ExperimentError::Io {
            path: png.display().to_string(),
            source,
        }
    })?;

    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, figure.size).into_drawing_area();
        render(&root, figure).map_err(|e| plot_err(&svg, e))?;
        root.present().map_err(|e| plot_err(&svg, e))?;
    }
    write_atomic(&svg, text.as_bytes())?;
    Ok(vec![png, svg])
}

fn render<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    figure: &Figure,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let body = root
        .titled(&figure.title, ("sans-serif", 30))
        .map_err(|e| e.to_string())?;
    let areas = body.split_evenly((1, figure.panels.len().max(1)));
    for (area, panel) in areas.iter().zip(&figure.panels) {
        let (x, y) = ranges(panel);
        match panel.y_scale {
            Scale::Linear => draw_panel(area, panel, x, y.clone(), &|v: &f64| format_linear(*v))?,
            Scale::Log => draw_panel(area, panel, x, y.log_scale(), &|v: &f64| format!("{v:.0e}"))?,
        }
    }
    Ok(())
}

fn format_linear(v: f64) -> String {
    if v == 0.0 || (1e-2..1e5).contains(&v.abs()) {
        let s = format!("{v:.2}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.1e}")
    }
}

/// Points of a series that can be drawn on the panel's scale.
fn drawable<'a>(panel: &Panel, s: &'a Series) -> impl Iterator<Item = (f64, f64)> + 'a {
    let log = panel.y_scale == Scale::Log;
    s.points
        .iter()
        .copied()
        .filter(move |&(x, y)| x.is_finite() && y.is_finite() && (!log || y > 0.0))
}

/// X and y ranges that hold every drawable point (and the reference line).
fn ranges(panel: &Panel) -> (Range<f64>, Range<f64>) {
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for s in &panel.series {
        for (x, y) in drawable(panel, s) {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
    }
    if let Some((r, _)) = &panel.reference {
        if panel.y_scale == Scale::Linear || *r > 0.0 {
            y0 = y0.min(*r);
            y1 = y1.max(*r);
        }
    }
    if let Some(m) = panel.y_min {
        y0 = y0.max(m);
        y1 = y1.max(m);
    }
    if let Some((a, b)) = panel.x_range {
        (x0, x1) = (a, b);
    }
    if !(x0.is_finite() && x1.is_finite()) {
        (x0, x1) = (0.0, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    match panel.y_scale {
        Scale::Linear => {
            if !(y0.is_finite() && y1.is_finite()) {
                (y0, y1) = (0.0, 1.0);
            }
            if y0 >= 0.0 {
                y0 = 0.0;
            }
            if y1 <= y0 {
                y1 = y0 + 1.0;
            }
            (x0..x1, y0..y1 + 0.05 * (y1 - y0))
        }
        Scale::Log => {
            if !(y0.is_finite() && y1.is_finite()) {
                (y0, y1) = (1e-6, 1.0);
            }
            // A decade below the smallest value (so a line at the minimum stays off the
            // axis), and half again above the largest.
            let lo = 10f64.powf((y0 / 1.2).log10().floor());
            let mut hi = 1.5 * y1;
            if hi <= lo {
                hi = lo * 10.0;
            }
            (x0..x1, lo..hi)
        }
    }
}

fn draw_panel<DB, Y>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    x: Range<f64>,
    y: Y,
    y_format: &dyn Fn(&f64) -> String,
) -> Result<(), String>
where
    DB: DrawingBackend,
    Y: AsRangedCoord<Value = f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let (x0, x1) = (x.start, x.end);
    // The legend gets its own column right of the axes, so it never hides a line.
    let mut labels: Vec<(&str, ShapeStyle, bool)> = panel
        .series
        .iter()
        .map(|s| (s.label.as_str(), s.color.stroke_width(2), false))
        .collect();
    if let Some((_, label)) = &panel.reference {
        labels.push((label.as_str(), BLACK.stroke_width(1), true));
    }
    let longest = labels
        .iter()
        .map(|(l, _, _)| l.chars().count())
        .max()
        .unwrap_or(0) as u32;
    let legend_width = if labels.is_empty() {
        0
    } else {
        50 + 9 * longest
    };
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 22))
        .margin(15)
        .margin_right(15 + legend_width)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(x, y)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .x_label_formatter(&|v: &f64| format_linear(*v))
        .y_label_formatter(y_format)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .draw()
        .map_err(e)?;
    let floor = panel.y_min;
    for s in &panel.series {
        let points = drawable(panel, s).map(move |(x, y)| (x, floor.map_or(y, |f| y.max(f))));
        chart
            .draw_series(LineSeries::new(points, s.color.stroke_width(2)))
            .map_err(e)?;
    }
    if let Some((r, _)) = &panel.reference {
        chart
            .draw_series(DashedLineSeries::new(
                [(x0, *r), (x1, *r)],
                8,
                6,
                BLACK.stroke_width(1),
            ))
            .map_err(e)?;
    }
    let (width, _) = area.dim_in_pixel();
    let left = width as i32 - legend_width as i32;
    let font = ("sans-serif", 15)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for (i, (label, style, dashed)) in labels.iter().enumerate() {
        let y = 70 + 24 * i as i32;
        if *dashed {
            area.draw(&PathElement::new(vec![(left, y), (left + 9, y)], *style))
                .map_err(e)?;
            area.draw(&PathElement::new(
                vec![(left + 15, y), (left + 24, y)],
                *style,
            ))
            .map_err(e)?;
        } else {
            area.draw(&PathElement::new(vec![(left, y), (left + 24, y)], *style))
                .map_err(e)?;
        }
        area.draw(&Text::new(label.to_string(), (left + 32, y), font.clone()))
            .map_err(e)?;
    }
    Ok(())
}
