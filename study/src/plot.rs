//! The study's log-log figures, drawn by `plotters` into an RGB8 buffer and written as PNG:
//! a title, both axes on log scales with their titles and tick labels, one colour per
//! series (markers and connecting lines) and a legend to the right of the plot.
//!
//! Text is set in Noto Sans, embedded at compile time (`ttf-noto-sans`), so a figure
//! looks the same on any machine and needs no system fonts.
//!
//! Points with a non-positive or non-finite coordinate are skipped (a log axis cannot show
//! them); a plot without points still draws its axes over one decade.
//!
//! ```no_run
//! use magg_study::plot::{Plot, Series, PALETTE};
//! let mut p = Plot::new("Error against time", "Seconds", "Relative MSE");
//! p.series.push(Series::new("light rays", vec![(0.5, 1e-2), (2.0, 3e-3)], PALETTE[0]));
//! p.write(std::path::Path::new("error.png"))?;
//! # Ok::<(), magg_study::StudyError>(())
//! ```

use crate::error::{Result, StudyError};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

/// Default canvas width.
pub const WIDTH: u32 = 800;
/// Default canvas height.
pub const HEIGHT: u32 = 560;

/// Width of the legend column to the right of the plot.
const LEGEND: u32 = 210;

/// The font family the figures use, registered from the embedded Noto Sans.
const FONT: &str = "sans-serif";

/// Distinct series colours.
pub const PALETTE: [[u8; 3]; 10] = [
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
    [255, 127, 14],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [23, 190, 207],
    [188, 189, 34],
    [127, 127, 127],
];

/// One series: points (x, y) in data units.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Data points; drawn in x order when joined.
    pub points: Vec<(f64, f64)>,
    /// RGB colour.
    pub color: [u8; 3],
    /// Draw a marker at each point.
    pub markers: bool,
    /// Join the points with lines (in x order).
    pub lines: bool,
}

impl Series {
    /// A series with markers and lines.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>, color: [u8; 3]) -> Series {
        Series { label: label.into(), points, color, markers: true, lines: true }
    }

    /// The drawable points, in x order.
    fn sorted(&self) -> Vec<(f64, f64)> {
        let mut pts: Vec<(f64, f64)> = self.points.iter().copied().filter(valid).collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        pts
    }
}

/// A log-log plot.
#[derive(Clone, Debug)]
pub struct Plot {
    /// Title above the plot.
    pub title: String,
    /// Title of the x axis.
    pub x_label: String,
    /// Title of the y axis.
    pub y_label: String,
    /// Canvas width in pixels.
    pub width: u32,
    /// Canvas height in pixels.
    pub height: u32,
    /// The series, drawn in order (later on top).
    pub series: Vec<Series>,
}

fn valid(p: &(f64, f64)) -> bool {
    p.0.is_finite() && p.1.is_finite() && p.0 > 0.0 && p.1 > 0.0
}

/// Decade range (floor, ceil of log10) of `values`, at least one decade wide.
fn decades(values: impl Iterator<Item = f64>) -> (i32, i32) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values {
        lo = lo.min(v.log10());
        hi = hi.max(v.log10());
    }
    if !lo.is_finite() || !hi.is_finite() {
        return (0, 1);
    }
    let (lo, mut hi) = (lo.floor() as i32, hi.ceil() as i32);
    if hi <= lo {
        hi = lo + 1;
    }
    (lo, hi)
}

/// Text of a tick at `v`: three significant digits, plain for 1e-3..1e5, else `<m>e<e>`.
fn tick_label(v: f64) -> String {
    let rounded: f64 = format!("{v:.2e}").parse().unwrap_or(v);
    if (1e-3..1e5).contains(&rounded.abs()) {
        format!("{rounded}")
    } else {
        format!("{rounded:e}")
    }
}

/// Registers the embedded font with plotters, once per process.
fn font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| plotters::style::register_font(FONT, FontStyle::Normal, ttf_noto_sans::REGULAR).is_ok());
    if !ok {
        return Err(StudyError::Plot("the embedded Noto Sans font does not load".into()));
    }
    Ok(())
}

/// What drawing on the bitmap can fail with (plotters' errors, generic in the backend).
type DrawResult = std::result::Result<(), Box<dyn std::error::Error>>;

/// A plotters or encoder error as a study error.
fn drawing(e: impl std::fmt::Display) -> StudyError {
    StudyError::Plot(e.to_string())
}

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

impl Plot {
    /// An empty plot of the default size.
    pub fn new(title: impl Into<String>, x_label: impl Into<String>, y_label: impl Into<String>) -> Plot {
        Plot {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            width: WIDTH,
            height: HEIGHT,
            series: Vec::new(),
        }
    }

    /// The axes' ranges in data units: whole decades around every drawable point.
    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let pts = || self.series.iter().flat_map(|s| s.points.iter()).filter(|p| valid(p));
        let span = |(lo, hi): (i32, i32)| (10f64.powi(lo), 10f64.powi(hi));
        (span(decades(pts().map(|p| p.0))), span(decades(pts().map(|p| p.1))))
    }

    /// RGB8 pixels, row-major.
    pub fn render(&self) -> Result<Vec<u8>> {
        if !(self.width > LEGEND + 100 && self.height > 100) {
            return Err(StudyError::Plot(format!("plot {}x{} is too small", self.width, self.height)));
        }
        font()?;
        let mut px = vec![255; self.width as usize * self.height as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut px, (self.width, self.height)).into_drawing_area();
            let area = root.titled(&self.title, (FONT, 22).into_font().color(&BLACK)).map_err(drawing)?;
            let (chart_area, legend_area) = area.split_horizontally(self.width - LEGEND);
            self.draw_chart(&chart_area).map_err(drawing)?;
            self.draw_legend(&legend_area).map_err(drawing)?;
            root.present().map_err(drawing)?;
        }
        Ok(px)
    }

    fn draw_chart(&self, area: &DrawingArea<BitMapBackend<'_>, Shift>) -> DrawResult {
        let ((x0, x1), (y0, y1)) = self.ranges();
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
        chart
            .configure_mesh()
            .x_desc(self.x_label.as_str())
            .y_desc(self.y_label.as_str())
            .x_labels(12)
            .y_labels(12)
            .x_label_formatter(&|v| tick_label(*v))
            .y_label_formatter(&|v| tick_label(*v))
            .label_style((FONT, 14))
            .axis_desc_style((FONT, 16))
            .light_line_style(RGBColor(240, 240, 240))
            .bold_line_style(RGBColor(215, 215, 215))
            .draw()?;
        for s in &self.series {
            let color = rgb(s.color);
            let pts = s.sorted();
            if s.lines {
                chart.draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))?;
            }
            if s.markers {
                chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, BLACK.stroke_width(1))))?;
                chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
            }
        }
        Ok(())
    }

    /// One row per series: its line and marker, then its label.
    fn draw_legend(&self, area: &DrawingArea<BitMapBackend<'_>, Shift>) -> DrawResult {
        let style = (FONT, 14).into_font().color(&BLACK);
        for (i, s) in self.series.iter().enumerate() {
            let y = 24 + 20 * i as i32;
            let color = rgb(s.color);
            if s.lines {
                area.draw(&PathElement::new(vec![(4, y), (26, y)], color.stroke_width(2)))?;
            }
            if s.markers {
                area.draw(&Circle::new((15, y), 4, BLACK.stroke_width(1)))?;
                area.draw(&Circle::new((15, y), 3, color.filled()))?;
            }
            area.draw(&Text::new(s.label.as_str(), (34, y - 8), style.clone()))?;
        }
        Ok(())
    }

    /// PNG file bytes (RGB8).
    pub fn png(&self) -> Result<Vec<u8>> {
        let img = image::RgbImage::from_raw(self.width, self.height, self.render()?)
            .ok_or_else(|| StudyError::Plot("plot buffer size".into()))?;
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, image::ImageFormat::Png).map_err(drawing)?;
        Ok(out.into_inner())
    }

    /// Writes the PNG to `path`.
    pub fn write(&self, path: &Path) -> Result<()> {
        std::fs::write(path, self.png()?).map_err(StudyError::io("write", path))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(bytes: &[u8]) -> image::RgbImage {
        assert_eq!(image::guess_format(bytes).unwrap(), image::ImageFormat::Png);
        image::load_from_memory(bytes).unwrap().into_rgb8()
    }

    #[test]
    fn png_decodes_with_the_given_size_and_is_drawn() {
        let mut p = Plot::new("Title: a/b (c) 1e-3 + 50%", "Seconds", "Relative MSE");
        p.width = 640;
        p.height = 400;
        let c = [10, 200, 30];
        p.series.push(Series::new("a_b", vec![(0.1, 1e-3), (1.0, 1e-4), (10.0, 2e-5)], c));
        let img = decode(&p.png().unwrap());
        assert_eq!(img.dimensions(), (640, 400));
        assert!(img.pixels().any(|px| px.0 == c), "the series is drawn in its colour");
        let dark = img.pixels().filter(|px| px.0.iter().all(|&v| v < 100)).count();
        assert!(dark > 500, "text and axes are drawn ({dark} dark pixels)");
        // The title's row band holds text, the bottom-right corner stays white.
        assert!((0..640).flat_map(|x| (0..24).map(move |y| (x, y))).any(|(x, y)| img.get_pixel(x, y).0 != [255; 3]));
        assert_eq!(img.get_pixel(638, 398).0, [255, 255, 255]);
    }

    #[test]
    fn empty_and_invalid_series_still_plot() {
        let mut p = Plot::new("", "", "");
        p.series.push(Series::new("empty", vec![], PALETTE[2]));
        p.series.push(Series::new(
            "bad",
            vec![(0.0, 1.0), (-1.0, 2.0), (f64::NAN, 1.0), (1.0, f64::INFINITY)],
            PALETTE[3],
        ));
        assert_eq!(decode(&p.png().unwrap()).dimensions(), (WIDTH, HEIGHT));
        let none = Plot::new("Nothing", "x", "y");
        assert_eq!(decode(&none.png().unwrap()).width(), WIDTH);
        let tiny = Plot { width: 50, ..none };
        assert!(tiny.png().is_err());
    }

    #[test]
    fn labels_and_ranges() {
        assert_eq!(tick_label(1.0), "1");
        assert_eq!(tick_label(1000.0), "1000");
        assert_eq!(tick_label(0.01), "0.01");
        assert_eq!(tick_label(0.30000000000000004), "0.3");
        assert_eq!(tick_label(1e-5), "1e-5");
        assert_eq!(tick_label(2e6), "2e6");
        assert_eq!(decades([0.5, 3.0].into_iter()), (-1, 1));
        assert_eq!(decades([10.0].into_iter()), (1, 2));
        assert_eq!(decades(std::iter::empty()), (0, 1));
        let mut p = Plot::new("t", "x", "y");
        p.series.push(Series::new("s", vec![(2.0, 0.5)], PALETTE[0]));
        assert_eq!(p.ranges(), ((1.0, 10.0), (0.1, 1.0)));
    }
}
