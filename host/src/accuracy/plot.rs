//! A small raster plotter for the accuracy study's log-log plots, written as RGB8 PNG with
//! the `png` crate: white canvas, axes with decade ticks and labels, axis titles, a title,
//! one colour per series (points and connecting lines) and a legend. Text uses a built-in
//! 5x7 bitmap font (letters are drawn as capitals).
//!
//! Points with a non-positive or non-finite coordinate are skipped (a log axis cannot show
//! them); a plot without points still draws its axes over one decade.

use anyhow::Context;
use std::path::Path;

/// Default canvas width.
pub const WIDTH: u32 = 800;
/// Default canvas height.
pub const HEIGHT: u32 = 560;

const LEFT: i32 = 90;
const TOP: i32 = 50;
const BOTTOM: i32 = 60;
const RIGHT: i32 = 210;

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

const BLACK: [u8; 3] = [0, 0, 0];
const GRID: [u8; 3] = [225, 225, 225];

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

/// Text of the tick at 10^e: plain for 1e-3..=1e4, else `1e<e>`.
fn decade_label(e: i32) -> String {
    tick_label(1, e)
}

/// Text of the tick at m * 10^e (m a digit): plain for e in -3..=4, else `<m>e<e>`.
fn tick_label(m: u32, e: i32) -> String {
    match e {
        0..=4 => format!("{m}{}", "0".repeat(e as usize)),
        -3..=-1 => format!("0.{}{m}", "0".repeat((-e - 1) as usize)),
        _ => format!("{m}e{e}"),
    }
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

    fn ranges(&self) -> ((i32, i32), (i32, i32)) {
        let pts = || self.series.iter().flat_map(|s| s.points.iter()).filter(|p| valid(p));
        (decades(pts().map(|p| p.0)), decades(pts().map(|p| p.1)))
    }

    /// Plot area: left, top, right, bottom pixel.
    fn area(&self) -> (i32, i32, i32, i32) {
        let r = (self.width as i32 - RIGHT).max(LEFT + 10);
        let b = (self.height as i32 - BOTTOM).max(TOP + 10);
        (LEFT, TOP, r, b)
    }

    /// The pixel (column, row) of data point (x, y), or None when it is not drawable.
    pub fn pixel_of(&self, x: f64, y: f64) -> Option<(i32, i32)> {
        if !valid(&(x, y)) {
            return None;
        }
        let ((x0, x1), (y0, y1)) = self.ranges();
        let (l, t, r, b) = self.area();
        let fx = (x.log10() - x0 as f64) / (x1 - x0) as f64;
        let fy = (y.log10() - y0 as f64) / (y1 - y0) as f64;
        Some(((l as f64 + fx * (r - l) as f64).round() as i32, (b as f64 - fy * (b - t) as f64).round() as i32))
    }

    /// RGB8 pixels, row-major.
    pub fn render(&self) -> Vec<u8> {
        let mut c = Canvas::new(self.width, self.height);
        let ((x0, x1), (y0, y1)) = self.ranges();
        let (l, t, r, b) = self.area();
        let xpix = |e: f64| l as f64 + (e - x0 as f64) / (x1 - x0) as f64 * (r - l) as f64;
        let ypix = |e: f64| b as f64 - (e - y0 as f64) / (y1 - y0) as f64 * (b - t) as f64;
        // Grid and ticks.
        for e in x0..=x1 {
            let px = xpix(e as f64).round() as i32;
            c.line(px, t, px, b, GRID, 1);
            c.line(px, b, px, b + 6, BLACK, 1);
            let s = decade_label(e);
            c.text(px - text_width(&s, 1) / 2, b + 10, &s, 1, BLACK);
            if e < x1 {
                for m in 2..10 {
                    let px = xpix(e as f64 + (m as f64).log10()).round() as i32;
                    c.line(px, b, px, b + 3, BLACK, 1);
                    if x1 - x0 == 1 && (m == 2 || m == 5) {
                        let s = tick_label(m, e);
                        c.text(px - text_width(&s, 1) / 2, b + 10, &s, 1, BLACK);
                    }
                }
            }
        }
        for e in y0..=y1 {
            let py = ypix(e as f64).round() as i32;
            c.line(l, py, r, py, GRID, 1);
            c.line(l - 6, py, l, py, BLACK, 1);
            let s = decade_label(e);
            c.text(l - 9 - text_width(&s, 1), py - 3, &s, 1, BLACK);
            if e < y1 {
                for m in 2..10 {
                    let py = ypix(e as f64 + (m as f64).log10()).round() as i32;
                    c.line(l - 3, py, l, py, BLACK, 1);
                    if y1 - y0 == 1 && (m == 2 || m == 5) {
                        let s = tick_label(m, e);
                        c.text(l - 9 - text_width(&s, 1), py - 3, &s, 1, BLACK);
                    }
                }
            }
        }
        // Frame.
        c.line(l, t, r, t, BLACK, 1);
        c.line(l, b, r, b, BLACK, 1);
        c.line(l, t, l, b, BLACK, 1);
        c.line(r, t, r, b, BLACK, 1);
        // Titles.
        let w = self.width as i32;
        c.text((w - text_width(&self.title, 2)) / 2, 14, &self.title, 2, BLACK);
        c.text((l + r - text_width(&self.x_label, 1)) / 2, b + 30, &self.x_label, 1, BLACK);
        c.text_up(20, (t + b + text_width(&self.y_label, 1)) / 2, &self.y_label, 1, BLACK);
        // Series.
        for s in &self.series {
            let mut pts: Vec<(i32, i32)> =
                s.points.iter().filter_map(|&(x, y)| self.pixel_of(x, y)).collect::<Vec<_>>();
            if s.lines {
                let mut sorted: Vec<&(f64, f64)> = s.points.iter().filter(|p| valid(p)).collect();
                sorted.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
                let px: Vec<(i32, i32)> = sorted.iter().filter_map(|p| self.pixel_of(p.0, p.1)).collect();
                for w in px.windows(2) {
                    c.line(w[0].0, w[0].1, w[1].0, w[1].1, s.color, 2);
                }
            }
            if s.markers {
                pts.dedup();
                for (x, y) in pts {
                    c.rect(x - 3, y - 3, 7, 7, BLACK);
                    c.rect(x - 2, y - 2, 5, 5, s.color);
                }
            }
        }
        // Legend.
        let lx = r + 14;
        let max_chars = ((w - lx - 30) / 6).max(1) as usize;
        for (i, s) in self.series.iter().enumerate() {
            let ly = t + 6 + 14 * i as i32;
            if s.lines {
                c.line(lx, ly + 3, lx + 18, ly + 3, s.color, 2);
            }
            if s.markers {
                c.rect(lx + 6, ly, 7, 7, BLACK);
                c.rect(lx + 7, ly + 1, 5, 5, s.color);
            }
            let label: String = s.label.chars().take(max_chars).collect();
            c.text(lx + 24, ly, &label, 1, BLACK);
        }
        c.px
    }

    /// PNG file bytes (RGB8).
    pub fn png(&self) -> anyhow::Result<Vec<u8>> {
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, self.width, self.height);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc.write_header()?;
            w.write_image_data(&self.render())?;
            w.finish()?;
        }
        Ok(out)
    }

    /// Writes the PNG to `path`.
    pub fn write(&self, path: &Path) -> anyhow::Result<()> {
        std::fs::write(path, self.png()?).with_context(|| format!("cannot write {}", path.display()))
    }
}

struct Canvas {
    w: i32,
    h: i32,
    px: Vec<u8>,
}

impl Canvas {
    fn new(w: u32, h: u32) -> Canvas {
        Canvas { w: w as i32, h: h as i32, px: vec![255; w as usize * h as usize * 3] }
    }

    fn set(&mut self, x: i32, y: i32, c: [u8; 3]) {
        if x >= 0 && y >= 0 && x < self.w && y < self.h {
            let i = (y as usize * self.w as usize + x as usize) * 3;
            self.px[i..i + 3].copy_from_slice(&c);
        }
    }

    fn rect(&mut self, x: i32, y: i32, w: i32, h: i32, c: [u8; 3]) {
        for yy in y..y + h {
            for xx in x..x + w {
                self.set(xx, yy, c);
            }
        }
    }

    /// Bresenham line, `thick` pixels square pen.
    fn line(&mut self, x0: i32, y0: i32, x1: i32, y1: i32, c: [u8; 3], thick: i32) {
        let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
        let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
        let (mut x, mut y, mut err) = (x0, y0, dx + dy);
        loop {
            self.rect(x, y, thick, thick, c);
            if x == x1 && y == y1 {
                break;
            }
            let e2 = 2 * err;
            if e2 >= dy {
                err += dy;
                x += sx;
            }
            if e2 <= dx {
                err += dx;
                y += sy;
            }
        }
    }

    /// Text with its top-left corner at (x, y).
    fn text(&mut self, x: i32, y: i32, s: &str, scale: i32, c: [u8; 3]) {
        for (i, ch) in s.chars().enumerate() {
            let g = glyph(ch);
            for (row, bits) in g.iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) != 0 {
                        let px = x + (i as i32 * 6 + col) * scale;
                        self.rect(px, y + row as i32 * scale, scale, scale, c);
                    }
                }
            }
        }
    }

    /// Text rotated a quarter turn anticlockwise, reading upwards from (x, y).
    fn text_up(&mut self, x: i32, y: i32, s: &str, scale: i32, c: [u8; 3]) {
        for (i, ch) in s.chars().enumerate() {
            let g = glyph(ch);
            for (row, bits) in g.iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) != 0 {
                        let along = (i as i32 * 6 + col) * scale;
                        self.rect(x + row as i32 * scale, y - along - scale, scale, scale, c);
                    }
                }
            }
        }
    }
}

fn text_width(s: &str, scale: i32) -> i32 {
    (s.chars().count() as i32 * 6 - 1).max(0) * scale
}

/// The 5x7 glyph of `ch`, rows top to bottom, bit 4 leftmost; letters of either case
/// share the capital glyph; an unknown character is a hollow box.
fn glyph(ch: char) -> [u8; 7] {
    let up = ch.to_ascii_uppercase();
    FONT.iter().find(|(c, _)| *c == up).map(|(_, g)| *g).unwrap_or(UNKNOWN)
}

const UNKNOWN: [u8; 7] = [0b11111, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b11111];

#[rustfmt::skip]
const FONT: &[(char, [u8; 7])] = &[
    ('0', [0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110]),
    ('1', [0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('2', [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111]),
    ('3', [0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110]),
    ('4', [0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010]),
    ('5', [0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110]),
    ('6', [0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110]),
    ('7', [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000]),
    ('8', [0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110]),
    ('9', [0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100]),
    ('A', [0b01110, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001]),
    ('B', [0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110]),
    ('C', [0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110]),
    ('D', [0b11100, 0b10010, 0b10001, 0b10001, 0b10001, 0b10010, 0b11100]),
    ('E', [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111]),
    ('F', [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000]),
    ('G', [0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111]),
    ('H', [0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001]),
    ('I', [0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('J', [0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100]),
    ('K', [0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001]),
    ('L', [0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111]),
    ('M', [0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001]),
    ('N', [0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001]),
    ('O', [0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110]),
    ('P', [0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000]),
    ('Q', [0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101]),
    ('R', [0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001]),
    ('S', [0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110]),
    ('T', [0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100]),
    ('U', [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110]),
    ('V', [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100]),
    ('W', [0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010]),
    ('X', [0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001]),
    ('Y', [0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100]),
    ('Z', [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111]),
    ('.', [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b01100]),
    ('-', [0b00000, 0b00000, 0b00000, 0b11111, 0b00000, 0b00000, 0b00000]),
    ('+', [0b00000, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0b00000]),
    ('/', [0b00000, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b00000]),
    ('(', [0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010]),
    (')', [0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000]),
    (':', [0b00000, 0b01100, 0b01100, 0b00000, 0b01100, 0b01100, 0b00000]),
    (',', [0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b00100, 0b01000]),
    ('_', [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b11111]),
    ('%', [0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011]),
    ('=', [0b00000, 0b00000, 0b11111, 0b00000, 0b11111, 0b00000, 0b00000]),
    (' ', [0; 7]),
];

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
        let dec = png::Decoder::new(bytes);
        let mut reader = dec.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        buf.truncate(info.buffer_size());
        (info.width, info.height, buf)
    }

    fn at(buf: &[u8], w: u32, x: i32, y: i32) -> [u8; 3] {
        let i = (y as usize * w as usize + x as usize) * 3;
        [buf[i], buf[i + 1], buf[i + 2]]
    }

    #[test]
    fn png_decodes_with_the_given_size() {
        let mut p = Plot::new("Title: a/b (c) 1e-3 + 50%", "seconds", "relative mse");
        p.width = 640;
        p.height = 400;
        p.series.push(Series::new("a_b", vec![(0.1, 1e-3), (1.0, 1e-4), (10.0, 2e-5)], PALETTE[0]));
        let (w, h, buf) = decode(&p.png().unwrap());
        assert_eq!((w, h), (640, 400));
        assert_eq!(buf.len(), 640 * 400 * 3);
        assert!(buf.iter().any(|&v| v != 255), "something is drawn");
    }

    #[test]
    fn a_point_colours_its_pixel() {
        let mut p = Plot::new("t", "x", "y");
        let c = [10, 200, 30];
        // Decades 1..100 on both axes: (10, 10) is the centre of the plot area.
        p.series.push(Series { markers: false, ..Series::new("edges", vec![(1.0, 1.0), (100.0, 100.0)], PALETTE[1]) });
        p.series.push(Series { lines: false, ..Series::new("mid", vec![(10.0, 10.0)], c) });
        let (l, t, r, b) = p.area();
        let centre = ((l + r) / 2, (t + b) / 2);
        assert_eq!(p.pixel_of(10.0, 10.0), Some(centre));
        assert_eq!(p.pixel_of(0.0, 10.0), None);
        let (w, _, buf) = decode(&p.png().unwrap());
        assert_eq!(at(&buf, w, centre.0, centre.1), c);
        assert_eq!(at(&buf, w, centre.0 + 1, centre.1 - 1), c);
        assert_eq!(at(&buf, w, 2, p.height as i32 - 2), [255, 255, 255]);
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
        let (w, h, _) = decode(&p.png().unwrap());
        assert_eq!((w, h), (WIDTH, HEIGHT));
        let none = Plot::new("nothing", "x", "y");
        assert_eq!(decode(&none.png().unwrap()).0, WIDTH);
    }

    #[test]
    fn labels_and_ranges() {
        assert_eq!(decade_label(0), "1");
        assert_eq!(decade_label(3), "1000");
        assert_eq!(decade_label(-2), "0.01");
        assert_eq!(decade_label(-5), "1e-5");
        assert_eq!(tick_label(5, -3), "0.005");
        assert_eq!(tick_label(2, 1), "20");
        assert_eq!(decades([0.5, 3.0].into_iter()), (-1, 1));
        assert_eq!(decades([10.0].into_iter()), (1, 2));
        assert_eq!(decades(std::iter::empty()), (0, 1));
    }
}
