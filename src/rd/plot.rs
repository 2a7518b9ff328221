//! Plots of a sweep with `plotters`: PSNR-Y against bit rate per
//! predictor, and the bits split into header / motion / residual per
//! predictor and QP. Each as SVG and as PNG (text drawn with the bundled
//! DejaVu Sans, so no system font is needed).

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::sweep::{QualityAxis, RdPoint};

/// The files a plot call wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlotFiles {
    /// RD curves, SVG then PNG.
    pub rd: [PathBuf; 2],
    /// Stacked bits, SVG then PNG.
    pub bits: [PathBuf; 2],
}

fn register_fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is a constant of the binary: registering cannot fail on
        // input, and if it did the PNG would only lack its text.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    });
}

/// Why a plot could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// No points were given.
    #[error("nothing to plot")]
    Empty,
    /// The drawing backend failed (most often: the file could not be
    /// written); its message.
    #[error("{0}")]
    Draw(String),
}

type PlotResult<T> = Result<T, PlotError>;

/// The backends' errors are generic over the backend: keep their message.
fn err<E: std::fmt::Display>(e: E) -> PlotError {
    PlotError::Draw(e.to_string())
}

/// Series label: the codec, prefixed by the sequence when there are several.
fn series(points: &[RdPoint]) -> Vec<(String, Vec<&RdPoint>)> {
    let many = points.iter().any(|p| p.sequence != points[0].sequence);
    let mut out: Vec<(String, Vec<&RdPoint>)> = Vec::new();
    for p in points {
        let name = if many {
            format!("{} {}", p.sequence, p.codec)
        } else {
            p.codec.clone()
        };
        match out.iter_mut().find(|(n, _)| *n == name) {
            Some((_, v)) => v.push(p),
            None => out.push((name, vec![p])),
        }
    }
    for (_, v) in &mut out {
        v.sort_by(|a, b| a.kbps.total_cmp(&b.kbps));
    }
    out
}

/// The legend box, the same on every plot.
fn legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> PlotResult<()> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(err)
}

fn draw_rd<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    points: &[RdPoint],
    title: &str,
    axis: QualityAxis,
) -> PlotResult<()> {
    root.fill(&WHITE).map_err(err)?;
    let series = series(points);
    let (mut r0, mut r1, mut p0, mut p1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in points {
        r0 = r0.min(p.kbps);
        r1 = r1.max(p.kbps);
        p0 = p0.min(axis.of(p));
        p1 = p1.max(axis.of(p));
    }
    let (r0, r1) = (r0 * 0.9, r1 * 1.1);
    let (p0, p1) = (p0 - 0.5, p1 + 0.5);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(55)
        .build_cartesian_2d((r0..r1).log_scale(), p0..p1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("bit rate (kbit/s, log scale)")
        .y_desc(axis.label())
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    for (i, (name, pts)) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let xy: Vec<(f64, f64)> = pts.iter().map(|p| (p.kbps, axis.of(p))).collect();
        chart
            .draw_series(LineSeries::new(xy.clone(), color.stroke_width(2)))
            .map_err(err)?
            .label(name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
        // Distinct markers as well as colours.
        match i % 3 {
            0 => chart.draw_series(xy.iter().map(|&c| Circle::new(c, 4, color.filled()))),
            1 => chart.draw_series(xy.iter().map(|&c| TriangleMarker::new(c, 5, color.filled()))),
            _ => chart.draw_series(xy.iter().map(|&c| Cross::new(c, 5, color.stroke_width(2)))),
        }
        .map_err(err)?;
    }
    legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present().map_err(err)
}

/// A bar of the bit split: its label (the QP) and kbit/s per category
/// (header, motion, residual).
type BitBar = (String, [f64; 3]);

/// A series' bars: its name, first bar and bar count (for its caption).
type BarGroup = (String, usize, usize);

/// One bar per point, grouped by series then QP, and the groups.
fn bit_bars(points: &[RdPoint]) -> (Vec<BitBar>, Vec<BarGroup>) {
    let mut bars = Vec::new();
    let mut groups = Vec::new();
    for (name, mut pts) in series(points) {
        pts.sort_by(|a, b| a.q.total_cmp(&b.q));
        groups.push((name.clone(), bars.len(), pts.len()));
        for p in pts {
            let seconds = p.bytes as f64 * 8.0 / (p.kbps * 1000.0).max(1e-9);
            let k = |b: u64| b as f64 / seconds.max(1e-9) / 1000.0;
            bars.push((
                format!("{}", p.q),
                [k(p.bits_header), k(p.bits_motion), k(p.bits_residual)],
            ));
        }
    }
    (bars, groups)
}

fn draw_bits<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    points: &[RdPoint],
    title: &str,
) -> PlotResult<()> {
    root.fill(&WHITE).map_err(err)?;
    let (bars, groups) = bit_bars(points);
    let top = bars
        .iter()
        .map(|(_, b)| b.iter().sum::<f64>())
        .fold(1.0, f64::max)
        * 1.1;
    let n = bars.len();
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d((0..n).into_segmented(), 0f64..top)
        .map_err(err)?;
    let labels: Vec<String> = bars.iter().map(|(l, _)| l.clone()).collect();
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n.max(1))
        .x_label_formatter(&|x| match x {
            SegmentValue::CenterOf(i) => labels.get(*i).cloned().unwrap_or_default(),
            _ => String::new(),
        })
        .x_label_style(("sans-serif", 12))
        .x_desc("QP, grouped by predictor")
        .y_desc("bit rate (kbit/s)")
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    let parts = [
        ("header", BLUE.mix(0.6)),
        ("motion", RED.mix(0.7)),
        ("residual", GREEN.mix(0.6)),
    ];
    for (k, (name, color)) in parts.iter().enumerate() {
        let color = *color;
        chart
            .draw_series(bars.iter().enumerate().map(|(i, (_, b))| {
                let base: f64 = b[..k].iter().sum();
                let mut bar = Rectangle::new(
                    [
                        (SegmentValue::Exact(i), base),
                        (SegmentValue::Exact(i + 1), base + b[k]),
                    ],
                    color.filled(),
                );
                bar.set_margin(0, 0, 3, 3);
                bar
            }))
            .map_err(err)?
            .label(*name)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], color.filled()));
    }
    for (name, first, count) in &groups {
        let height = bars[*first..first + count]
            .iter()
            .map(|(_, b)| b.iter().sum::<f64>())
            .fold(0.0, f64::max);
        chart
            .draw_series(std::iter::once(Text::new(
                name.clone(),
                (SegmentValue::Exact(*first), height + top * 0.035),
                ("sans-serif", 13),
            )))
            .map_err(err)?;
    }
    legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    root.present().map_err(err)
}

/// Writes `path` (SVG) and the PNG beside it with the RD curves, and
/// `<stem>_bits.svg` / `.png` with the bit split. `subject` (the sequences'
/// names) starts both titles: "SUBJECT: PSNR-Y against rate" and
/// "SUBJECT: bits per category (header, motion, residual)".
pub fn plot(points: &[RdPoint], path: &Path, subject: &str, axis: QualityAxis) -> PlotResult<PlotFiles> {
    let label = axis.label();
    let name = label.split(" (").next().unwrap_or(&label);
    let title = format!("{subject}: {name} against rate");
    let title = title.as_str();
    if points.is_empty() {
        return Err(PlotError::Empty);
    }
    register_fonts();
    let stem = path.with_extension("");
    let name = |suffix: &str, ext: &str| PathBuf::from(format!("{}{suffix}.{ext}", stem.display()));
    let files = PlotFiles {
        rd: [name("", "svg"), name("", "png")],
        bits: [name("_bits", "svg"), name("_bits", "png")],
    };
    let size = (960, 640);
    let bits_size = (960.max(40 * points.len() as u32 + 200), 640);
    draw_rd(
        SVGBackend::new(&files.rd[0], size).into_drawing_area(),
        points,
        title,
        axis,
    )?;
    draw_rd(
        BitMapBackend::new(&files.rd[1], size).into_drawing_area(),
        points,
        title,
        axis,
    )?;
    let bits_title = format!("{subject}: bits per category (header, motion, residual)");
    draw_bits(
        SVGBackend::new(&files.bits[0], bits_size).into_drawing_area(),
        points,
        &bits_title,
    )?;
    draw_bits(
        BitMapBackend::new(&files.bits[1], bits_size).into_drawing_area(),
        points,
        &bits_title,
    )?;
    Ok(files)
}

/// A line plot of named series of (x, y) points: PNG when `path` ends in
/// .png, SVG otherwise. Used for camera paths and the like.
pub fn plot_lines(
    path: &Path,
    title: &str,
    labels: (&str, &str),
    series: &[(String, Vec<(f64, f64)>)],
) -> PlotResult<()> {
    if series.iter().all(|s| s.1.is_empty()) {
        return Err(PlotError::Empty);
    }
    register_fonts();
    if path.extension().is_some_and(|e| e == "png") {
        draw_lines(
            BitMapBackend::new(path, (960, 480)).into_drawing_area(),
            title,
            labels,
            series,
        )
    } else {
        draw_lines(
            SVGBackend::new(path, (960, 480)).into_drawing_area(),
            title,
            labels,
            series,
        )
    }
}

fn draw_lines<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    labels: (&str, &str),
    series: &[(String, Vec<(f64, f64)>)],
) -> PlotResult<()> {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in series.iter().flat_map(|s| s.1.iter()) {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    let pad = ((y1 - y0) * 0.05).max(0.5);
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(55)
        .build_cartesian_2d(x0..x1.max(x0 + 1.0), (y0 - pad)..(y1 + pad))
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(labels.0)
        .y_desc(labels.1)
        .draw()
        .map_err(err)?;
    for (k, (name, pts)) in series.iter().enumerate() {
        let colour = Palette99::pick(k).to_rgba();
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(2)))
            .map_err(err)?
            .label(name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
    }
    legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    root.present().map_err(err)
}
