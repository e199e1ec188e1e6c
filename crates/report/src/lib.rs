//! Plots and run reports.
//!
//! Every chart is written twice, as PNG (for pages and chat) and SVG (for papers), each through a
//! temporary file renamed into place, so a reader never sees half a picture. Charts:
//! [`learning_curves`] from a run's `metrics.csv` (return, early terminations, every reward term),
//! [`success_map`] (trial start positions around the chair, coloured by outcome),
//! [`transition_matrix`] (counts of skill `from → to`), [`curriculum_schedule`] (the open zone
//! and the windowed success rate over training) and [`grouped_bars`] (an ablation's success per
//! zone and variant).
//!
//! PNG text needs a TrueType font: the first of [`FONT_CANDIDATES`] that exists (or the file
//! named by `REPERTOIRE_FONT`) is registered once per process; `scripts/setup.sh` installs
//! Debian's DejaVu fonts where none is present.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;

mod csv;

pub use csv::{Table, read_table};

/// Errors, each naming the file it is about.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A file's content is not what it should be.
    #[error("{path}: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong, and where.
        message: String,
    },
    /// Drawing failed.
    #[error("{path}: drawing failed: {message}")]
    Draw {
        /// The chart being drawn.
        path: PathBuf,
        /// The backend's message.
        message: String,
    },
    /// No font for PNG text.
    #[error("no TrueType font for chart text (looked for $REPERTOIRE_FONT and {0}); run scripts/setup.sh")]
    NoFont(String),
}

/// Result with [`ReportError`].
pub type Result<T> = std::result::Result<T, ReportError>;

/// Fonts tried, in order, for PNG text.
pub const FONT_CANDIDATES: [&str; 4] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
];

/// Registers the chart font once; later calls return the first call's outcome.
pub fn ensure_font() -> Result<()> {
    static FONT: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    let outcome = FONT.get_or_init(|| {
        let env = std::env::var_os("REPERTOIRE_FONT").map(PathBuf::from);
        let found = env.into_iter().chain(FONT_CANDIDATES.iter().map(PathBuf::from)).find(|p| p.is_file());
        let Some(path) = found else { return Err(FONT_CANDIDATES.join(", ")) };
        let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        // The font registry keeps `'static` bytes; one font per process.
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
            .map_err(|_| format!("{} is not a TrueType font", path.display()))
    });
    outcome.clone().map_err(ReportError::NoFont)
}

/// Chart size in pixels (PNG) and user units (SVG).
pub const SIZE: (u32, u32) = (900, 540);

/// Palette for series and skills.
pub const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// Draws the same body on a PNG and an SVG canvas (the body is expanded once per backend).
macro_rules! render {
    ($stem:expr, $size:expr, |$area:ident| $body:expr) => {
        render_with(
            $stem,
            $size,
            |$area: &DrawingArea<BitMapBackend, Shift>| -> std::result::Result<(), String> { $body },
            |$area: &DrawingArea<SVGBackend, Shift>| -> std::result::Result<(), String> { $body },
        )
    };
}

/// Draws `png_draw` and `svg_draw` (the same picture) on a PNG and an SVG canvas of `size` and
/// writes `stem.png` and `stem.svg` atomically; returns both paths.
pub fn render_with<P, S>(stem: &Path, size: (u32, u32), png_draw: P, svg_draw: S) -> Result<[PathBuf; 2]>
where
    P: Fn(&DrawingArea<BitMapBackend, Shift>) -> std::result::Result<(), String>,
    S: Fn(&DrawingArea<SVGBackend, Shift>) -> std::result::Result<(), String>,
{
    ensure_font()?;
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    if let Some(dir) = png.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| ReportError::Io { path: dir.to_path_buf(), source })?;
    }
    let draw_err = |path: &Path, message: String| ReportError::Draw { path: path.to_path_buf(), message };

    // PNG: the encoder picks the format from the extension, so the temporary name ends in .png.
    let tmp_png = repertoire_files::temp_sibling(&png);
    let drawn = (|| {
        let area = BitMapBackend::new(&tmp_png, size).into_drawing_area();
        area.fill(&WHITE).map_err(|e| draw_err(&png, e.to_string()))?;
        png_draw(&area).map_err(|m| draw_err(&png, m))?;
        area.present().map_err(|e| draw_err(&png, e.to_string()))
    })();
    if let Err(e) = drawn {
        let _ = std::fs::remove_file(&tmp_png);
        return Err(e);
    }
    repertoire_files::commit(&tmp_png, &png).map_err(|e| ReportError::Io { path: e.path, source: e.source })?;

    let mut text = String::new();
    {
        let area = SVGBackend::with_string(&mut text, size).into_drawing_area();
        area.fill(&WHITE).map_err(|e| draw_err(&svg, e.to_string()))?;
        svg_draw(&area).map_err(|m| draw_err(&svg, m))?;
        area.present().map_err(|e| draw_err(&svg, e.to_string()))?;
    }
    write_atomic(&svg, text.as_bytes())?;
    Ok([png, svg])
}

/// Writes `bytes` to `path` through a temporary sibling renamed into place.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    repertoire_files::write_atomic(path, bytes).map_err(|e| ReportError::Io { path: e.path, source: e.source })
}

/// One named line.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend entry.
    pub name: String,
    /// Points, x ascending; non-finite values are skipped.
    pub points: Vec<(f64, f64)>,
}

/// A legend entry's marker: a short line in the series' style.
fn legend_line(style: ShapeStyle) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style)
}

/// Axis range over all finite values, padded; a flat or empty range still gets a height.
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) =
        values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { lo.abs().max(1.0) * 0.05 };
    (lo - pad, hi + pad)
}

/// Draws `series` as lines into `area` with a title and axis labels.
fn lines<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> std::result::Result<(), String> {
    let xs = range(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let ys = range(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d(xs.0..xs.1, ys.0..ys.1)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_label_formatter(&|v| short(*v))
        .y_label_formatter(&|v| short(*v))
        .label_style(("sans-serif", 12))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| e.to_string())?;
    for (k, s) in series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let pts: Vec<(f64, f64)> = s.points.iter().copied().filter(|p| p.0.is_finite() && p.1.is_finite()).collect();
        chart
            .draw_series(LineSeries::new(pts, colour.stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label(s.name.clone())
            .legend(legend_line(colour.stroke_width(2)));
    }
    if series.len() > 1 {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(200, 200, 200))
            .label_font(("sans-serif", 12))
            .position(SeriesLabelPosition::LowerRight)
            .draw()
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// A tick label: `1.2M`, `250k`, `0.35`, `12`.
fn short(v: f64) -> String {
    let a = v.abs();
    if a >= 1e6 {
        format!("{:.1}M", v / 1e6)
    } else if a >= 1e4 {
        format!("{:.0}k", v / 1e3)
    } else if a >= 100.0 || v == v.round() {
        format!("{v:.0}")
    } else {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// A line chart of `series`.
pub fn line_chart(stem: &Path, title: &str, x_label: &str, y_label: &str, series: &[Series]) -> Result<[PathBuf; 2]> {
    render!(stem, SIZE, |a| lines(a, title, x_label, y_label, series))
}

/// Learning curves of a run from its `metrics.csv` (the learning core's columns): mean episode
/// return and early-termination rate against environment steps (`STEM-return`), and every
/// reward term `term_*` per step (episode sum ÷ mean episode length, `STEM-terms`).
pub fn learning_curves(metrics: &Path, stem: &Path) -> Result<Vec<PathBuf>> {
    let t = read_table(metrics)?;
    let steps = t.column("global_step")?;
    let ret = t.column("mean_return")?;
    let len = t.column("mean_length")?;
    let term = t.column("termination_rate")?;
    let pair = |ys: &[f64]| steps.iter().zip(ys).map(|(&x, &y)| (x, y)).collect::<Vec<_>>();
    let name =
        metrics.parent().and_then(Path::file_name).map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let mut out = Vec::new();
    let ret_stem = suffixed(stem, "-return");
    let series_ret = [Series { name: "mean return".into(), points: pair(&ret) }];
    let series_term = [Series { name: "early terminations".into(), points: pair(&term) }];
    out.extend(render!(&ret_stem, (SIZE.0, SIZE.1 + 200), |area| {
        let (top, bottom) = area.split_vertically((SIZE.1 + 200) / 2 + 60);
        lines(&top, &format!("{name}: mean episode return"), "environment steps", "return", &series_ret)?;
        lines(&bottom, "share of episodes ended early (falls)", "environment steps", "rate", &series_term)
    })?);
    let terms: Vec<Series> = t
        .headers
        .iter()
        .filter_map(|h| h.strip_prefix("term_").map(|n| (h, n)))
        .map(|(h, n)| {
            let col = t.column(h)?;
            Ok(Series {
                name: n.to_string(),
                points: steps
                    .iter()
                    .zip(col.iter().zip(&len))
                    .map(|(&x, (&s, &l))| (x, if l > 0.0 { s / l } else { f64::NAN }))
                    .collect(),
            })
        })
        .collect::<Result<_>>()?;
    if !terms.is_empty() {
        out.extend(line_chart(
            &suffixed(stem, "-terms"),
            &format!("{name}: reward terms per step"),
            "environment steps",
            "episode sum ÷ mean length",
            &terms,
        )?);
    }
    Ok(out)
}

/// `stem` with `suffix` appended to its file name.
fn suffixed(stem: &Path, suffix: &str) -> PathBuf {
    let name = stem.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    stem.with_file_name(format!("{name}{suffix}"))
}

/// One trial start for [`success_map`]: position in the chair's frame (x in front of the seat,
/// y to its left) and whether it succeeded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartPoint {
    /// Metres in front of the chair.
    pub x: f64,
    /// Metres to the chair's left.
    pub y: f64,
    /// Success.
    pub success: bool,
}

/// Trial starts around the chair (drawn at the origin, facing +x), green for success and red
/// for failure, with the success rate in each 0.5 m cell shaded behind them.
pub fn success_map(stem: &Path, title: &str, points: &[StartPoint]) -> Result<[PathBuf; 2]> {
    let reach = points.iter().map(|p| p.x.abs().max(p.y.abs())).fold(1.0f64, f64::max).ceil() + 0.25;
    render!(stem, (720, 720), |area| {
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(48)
            .build_cartesian_2d(-reach..reach, -reach..reach)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("← chair's left (m) · chair's right →")
            .x_label_formatter(&|v| format!("{:.1}", v.abs()))
            .y_desc("x: in front of the chair (m)")
            .label_style(("sans-serif", 12))
            .disable_mesh()
            .draw()
            .map_err(|e| e.to_string())?;
        // Cells: success rate of the starts inside, from red (0) to green (1). Seen from above
        // with the chair facing up the page: its left (+y) is the page's left.
        let cell = 0.5;
        let n = (2.0 * reach / cell).ceil() as i64;
        for i in 0..n {
            for j in 0..n {
                let (x0, y0) = (-reach + i as f64 * cell, -reach + j as f64 * cell);
                let inside: Vec<&StartPoint> =
                    points.iter().filter(|p| -p.y >= x0 && -p.y < x0 + cell && p.x >= y0 && p.x < y0 + cell).collect();
                if inside.is_empty() {
                    continue;
                }
                let rate = inside.iter().filter(|p| p.success).count() as f64 / inside.len() as f64;
                let colour = mix(RGBColor(244, 199, 195), RGBColor(183, 225, 180), rate);
                chart
                    .draw_series(std::iter::once(Rectangle::new([(x0, y0), (x0 + cell, y0 + cell)], colour.filled())))
                    .map_err(|e| e.to_string())?;
            }
        }
        // The chair: a 0.5 m square seat with its back behind it.
        chart
            .draw_series([
                Rectangle::new([(-0.25, -0.25), (0.25, 0.25)], RGBColor(120, 90, 60).filled()),
                Rectangle::new([(-0.25, -0.3), (0.25, -0.25)], RGBColor(80, 60, 40).filled()),
            ])
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(points.iter().map(|p| {
                let c = if p.success { RGBColor(30, 140, 40) } else { RGBColor(200, 40, 40) };
                Circle::new((-p.y, p.x), 2, c.filled())
            }))
            .map_err(|e| e.to_string())?;
        Ok(())
    })
}

/// Linear blend from `a` (t = 0) to `b` (t = 1).
fn mix(a: RGBColor, b: RGBColor, t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let f = |x: u8, y: u8| (f64::from(x) + t * (f64::from(y) - f64::from(x))).round() as u8;
    RGBColor(f(a.0, b.0), f(a.1, b.1), f(a.2, b.2))
}

/// A matrix of transition counts, rows `from`, columns `to`, each cell shaded by its share of
/// its row and labelled with its count.
pub fn transition_matrix(
    stem: &Path,
    title: &str,
    rows: &[String],
    cols: &[String],
    counts: &[Vec<u32>],
) -> Result<[PathBuf; 2]> {
    if counts.len() != rows.len() || counts.iter().any(|r| r.len() != cols.len()) {
        return Err(ReportError::Invalid {
            path: stem.to_path_buf(),
            message: format!("transition matrix is not {} × {}", rows.len(), cols.len()),
        });
    }
    let (w, h) = (160 + 110 * cols.len() as u32, 110 + 60 * rows.len() as u32);
    render!(stem, (w.max(420), h), |area| {
        let area = area.titled(title, ("sans-serif", 18)).map_err(|e| e.to_string())?;
        let (label_w, label_h) = (130i32, 40i32);
        let cw = 110i32;
        let ch = 60i32;
        let text = |s: &str, x: i32, y: i32| Text::new(s.to_string(), (x, y), ("sans-serif", 13).into_font());
        area.draw(&text("from ↓ / to →", 6, 10)).map_err(|e| e.to_string())?;
        for (j, c) in cols.iter().enumerate() {
            area.draw(&text(c, label_w + j as i32 * cw + 8, label_h - 22)).map_err(|e| e.to_string())?;
        }
        for (i, (r, row)) in rows.iter().zip(counts).enumerate() {
            let y = label_h + i as i32 * ch;
            area.draw(&text(r, 6, y + ch / 2 - 7)).map_err(|e| e.to_string())?;
            let total: u32 = row.iter().sum();
            for (j, &n) in row.iter().enumerate() {
                let x = label_w + j as i32 * cw;
                let share = if total > 0 { f64::from(n) / f64::from(total) } else { 0.0 };
                let fill = mix(RGBColor(250, 250, 250), RGBColor(31, 119, 180), share);
                area.draw(&Rectangle::new([(x, y), (x + cw - 4, y + ch - 4)], fill.filled()))
                    .map_err(|e| e.to_string())?;
                let ink = if share > 0.55 { WHITE } else { BLACK };
                area.draw(&Text::new(
                    n.to_string(),
                    (x + 10, y + ch / 2 - 8),
                    ("sans-serif", 14).into_font().color(&ink),
                ))
                .map_err(|e| e.to_string())?;
            }
        }
        Ok(())
    })
}

/// One row of [`grouped_bars`]: its label and one `(mean, sd)` per group, in percent.
#[derive(Debug, Clone, PartialEq)]
pub struct BarRow {
    /// Row label (e.g. an ablation's variant).
    pub label: String,
    /// Mean and standard deviation per group (sd 0: no whisker).
    pub values: Vec<(f64, f64)>,
}

/// Horizontal grouped bars on a 0–100 % scale: one row per entry of `rows` (its label on the
/// left), one coloured bar per group (named in the legend) labelled with its mean, and a whisker
/// of ± one sd where the sd is above 0. For an ablation's success per zone and variant.
pub fn grouped_bars(stem: &Path, title: &str, groups: &[String], rows: &[BarRow]) -> Result<[PathBuf; 2]> {
    if let Some(r) = rows.iter().find(|r| r.values.len() != groups.len()) {
        return Err(ReportError::Invalid {
            path: stem.to_path_buf(),
            message: format!("row `{}` has {} values for {} groups", r.label, r.values.len(), groups.len()),
        });
    }
    const BAR: i32 = 15;
    const GAP: i32 = 12;
    const TOP: i32 = 78;
    let row_h = BAR * groups.len().max(1) as i32 + GAP;
    let height = (TOP + row_h * rows.len() as i32 + 40).max(200) as u32;
    render!(stem, (SIZE.0 + 100, height), |area| {
        let (w, h) = area.dim_in_pixel();
        let (left, right) = (300i32, w as i32 - 50);
        let x = |p: f64| left + ((right - left) as f64 * p.clamp(0.0, 100.0) / 100.0).round() as i32;
        let text =
            |s: &str, px: i32, py: i32, size: u32| Text::new(s.to_string(), (px, py), ("sans-serif", size).into_font());
        area.draw(&text(title, 10, 10, 18)).map_err(|e| e.to_string())?;
        for (k, g) in groups.iter().enumerate() {
            let lx = left + 150 * k as i32;
            let c = COLOURS[k % COLOURS.len()];
            area.draw(&Rectangle::new([(lx, 44), (lx + 14, 58)], c.filled())).map_err(|e| e.to_string())?;
            area.draw(&text(g, lx + 20, 43, 14)).map_err(|e| e.to_string())?;
        }
        let bottom = h as i32 - 34;
        for tick in [0.0, 25.0, 50.0, 75.0, 100.0] {
            let tx = x(tick);
            area.draw(&PathElement::new(vec![(tx, TOP - 6), (tx, bottom)], RGBColor(225, 225, 225)))
                .map_err(|e| e.to_string())?;
            area.draw(&text(&format!("{tick:.0} %"), tx - 12, bottom + 8, 12)).map_err(|e| e.to_string())?;
        }
        for (i, row) in rows.iter().enumerate() {
            let y0 = TOP + row_h * i as i32;
            let label: String = row.label.chars().take(42).collect();
            area.draw(&text(&label, 10, y0 + (row_h - GAP) / 2 - 8, 14)).map_err(|e| e.to_string())?;
            for (k, &(mean, sd)) in row.values.iter().enumerate() {
                let y = y0 + BAR * k as i32;
                let c = COLOURS[k % COLOURS.len()];
                if mean.is_finite() {
                    area.draw(&Rectangle::new([(x(0.0), y), (x(mean).max(x(0.0) + 1), y + BAR - 2)], c.filled()))
                        .map_err(|e| e.to_string())?;
                    if sd.is_finite() && sd > 0.0 {
                        let mid = y + BAR / 2 - 1;
                        let (a, b) = (x(mean - sd), x(mean + sd));
                        area.draw(&PathElement::new(vec![(a, mid), (b, mid)], BLACK)).map_err(|e| e.to_string())?;
                        for end in [a, b] {
                            area.draw(&PathElement::new(vec![(end, mid - 3), (end, mid + 3)], BLACK))
                                .map_err(|e| e.to_string())?;
                        }
                    }
                    let lx = x(mean + if sd.is_finite() { sd.max(0.0) } else { 0.0 }) + 5;
                    area.draw(&text(&format!("{mean:.1}"), lx, y + 1, 11)).map_err(|e| e.to_string())?;
                }
            }
        }
        Ok(())
    })
}

/// A grid of rates (0–1; `None`: no trials) over two swept quantities: row `i`, column `j` is
/// `rates[i][j]` at `ys[i]`, `xs[j]`, shaded from red (0) to green (1) and labelled with the rate
/// in percent and its trial count. For pick-up success over start positions and catch rate over
/// throw speeds.
pub fn grid_map(
    stem: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    xs: &[f64],
    ys: &[f64],
    cells: &[Vec<(Option<f64>, usize)>],
) -> Result<[PathBuf; 2]> {
    if cells.len() != ys.len() || cells.iter().any(|r| r.len() != xs.len()) || xs.is_empty() || ys.is_empty() {
        return Err(ReportError::Invalid {
            path: stem.to_path_buf(),
            message: format!("grid is not {} × {} (and non-empty)", ys.len(), xs.len()),
        });
    }
    let (cw, ch, label_w, top) = (72i32, 44i32, 90i32, 50i32);
    let w = (label_w + cw * xs.len() as i32 + 20).max(480) as u32;
    let h = (top + ch * ys.len() as i32 + 60) as u32;
    render!(stem, (w, h), |area| {
        let area = area.titled(title, ("sans-serif", 18)).map_err(|e| e.to_string())?;
        let text = |s: String, x: i32, y: i32, size: u32| Text::new(s, (x, y), ("sans-serif", size).into_font());
        area.draw(&text(y_label.to_string(), 6, 4, 13)).map_err(|e| e.to_string())?;
        // Rows from the top: the largest y first, as on a plot.
        for (r, i) in (0..ys.len()).rev().enumerate() {
            let y = top + r as i32 * ch;
            area.draw(&text(format!("{:.2}", ys[i]), 10, y + ch / 2 - 7, 12)).map_err(|e| e.to_string())?;
            for (j, &(rate, n)) in cells[i].iter().enumerate() {
                let x = label_w + j as i32 * cw;
                let fill = match rate {
                    Some(v) => mix(RGBColor(244, 160, 150), RGBColor(120, 200, 120), v),
                    None => RGBColor(235, 235, 235),
                };
                area.draw(&Rectangle::new([(x, y), (x + cw - 3, y + ch - 3)], fill.filled()))
                    .map_err(|e| e.to_string())?;
                let label = rate.map_or_else(|| "–".to_string(), |v| format!("{:.0}%", 100.0 * v));
                area.draw(&text(label, x + 8, y + 6, 13)).map_err(|e| e.to_string())?;
                area.draw(&text(format!("n={n}"), x + 8, y + 24, 10)).map_err(|e| e.to_string())?;
            }
        }
        let bottom = top + ch * ys.len() as i32 + 6;
        for (j, v) in xs.iter().enumerate() {
            area.draw(&text(format!("{v:.2}"), label_w + j as i32 * cw + 14, bottom, 12)).map_err(|e| e.to_string())?;
        }
        area.draw(&text(x_label.to_string(), label_w, bottom + 22, 13)).map_err(|e| e.to_string())?;
        Ok(())
    })
}

/// One curriculum sample: after `episodes` training episodes, zone `zone` (index into the
/// schedule's zones) is the newest open zone and the windowed success rate is `success`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurriculumPoint {
    /// Training iteration.
    pub iteration: f64,
    /// Index of the newest open zone.
    pub zone: usize,
    /// Windowed success rate (NaN before the window fills).
    pub success: f64,
}

/// The zone curriculum over training: the newest open zone as a step line and the windowed
/// success rate with the advance threshold.
pub fn curriculum_schedule(
    stem: &Path,
    zones: &[String],
    threshold: f64,
    points: &[CurriculumPoint],
) -> Result<[PathBuf; 2]> {
    let max_it = points.iter().map(|p| p.iteration).fold(1.0, f64::max);
    render!(stem, SIZE, |area| {
        let mut chart = ChartBuilder::on(area)
            .caption("zone curriculum", ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .right_y_label_area_size(70)
            .build_cartesian_2d(0.0..max_it, 0.0..1.05)
            .map_err(|e| e.to_string())?
            .set_secondary_coord(0.0..max_it, -0.5..(zones.len() as f64 - 0.5));
        chart
            .configure_mesh()
            .x_desc("iteration")
            .y_desc("windowed success rate")
            .label_style(("sans-serif", 12))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(|e| e.to_string())?;
        let names = zones.to_vec();
        chart
            .configure_secondary_axes()
            .y_labels(zones.len().max(2))
            .y_label_formatter(&move |v| {
                let k = v.round();
                if (v - k).abs() < 1e-6 && k >= 0.0 {
                    names.get(k as usize).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            })
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(LineSeries::new([(0.0, threshold), (max_it, threshold)], RGBColor(60, 60, 60).stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label(format!("advance at {:.0}%", 100.0 * threshold))
            .legend(legend_line(RGBColor(60, 60, 60).stroke_width(2)));
        let rate: Vec<(f64, f64)> =
            points.iter().filter(|p| p.success.is_finite()).map(|p| (p.iteration, p.success)).collect();
        chart
            .draw_series(LineSeries::new(rate, COLOURS[0].stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label("success (window)")
            .legend(legend_line(COLOURS[0].stroke_width(2)));
        let mut steps = Vec::new();
        for p in points {
            if let Some(&(_, z)) = steps.last() {
                steps.push((p.iteration, z));
            }
            steps.push((p.iteration, p.zone as f64));
        }
        chart
            .draw_secondary_series(LineSeries::new(steps, COLOURS[1].stroke_width(3)))
            .map_err(|e| e.to_string())?
            .label("newest open zone")
            .legend(legend_line(COLOURS[1].stroke_width(3)));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(200, 200, 200))
            .label_font(("sans-serif", 12))
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(|e| e.to_string())?;
        Ok(())
    })
}
