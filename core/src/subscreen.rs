//! Subscreens (paper §4.6): the rectangles of pixels the viewing pass hands out, one at a
//! time, to the nodes that ask. The screen is tiled row by row; a crop window keeps the
//! whole frame's tiling; the cluster's scheduler splits a subscreen by rows to give an
//! idle node the unstarted part of a busy node's (adaptive redivision).
//!
//! ```
//! use magg_core::subscreen::{pixels, tile, Subscreen};
//! let tiles = tile(40, 20, 16);
//! assert_eq!(tiles.len(), 6);
//! assert_eq!(tiles[2], Subscreen { x: 32, y: 0, w: 8, h: 16 });
//! assert_eq!(pixels(&tiles), 800);
//! ```

/// A rectangle of pixels: the paper's subscreen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Subscreen {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width in pixels.
    pub w: u32,
    /// Height in pixels.
    pub h: u32,
}

impl Subscreen {
    /// Number of pixels.
    pub fn pixels(&self) -> u64 {
        self.w as u64 * self.h as u64
    }
}

/// Splits the screen into subscreens of `edge` pixels, row by row.
pub fn tile(width: u32, height: u32, edge: u32) -> Vec<Subscreen> {
    let edge = edge.max(1);
    let mut v = Vec::new();
    let mut y = 0;
    while y < height {
        let mut x = 0;
        while x < width {
            v.push(Subscreen { x, y, w: edge.min(width - x), h: edge.min(height - y) });
            x += edge;
        }
        y += edge;
    }
    v
}

/// The parts of `tiles` inside `window` (all of them for `None`), each cut to it: the
/// subscreens of a crop window keep the whole frame's tiling, so that every pixel is
/// traced as in the whole frame.
pub fn clip(tiles: &[Subscreen], window: Option<Subscreen>) -> Vec<Subscreen> {
    let Some(w) = window else { return tiles.to_vec() };
    tiles
        .iter()
        .filter_map(|t| {
            let (x0, y0) = (t.x.max(w.x), t.y.max(w.y));
            let (x1, y1) = ((t.x + t.w).min(w.x + w.w), (t.y + t.h).min(w.y + w.h));
            (x0 < x1 && y0 < y1).then_some(Subscreen { x: x0, y: y0, w: x1 - x0, h: y1 - y0 })
        })
        .collect()
}

/// Pixels of `tiles`.
pub fn pixels(tiles: &[Subscreen]) -> u64 {
    tiles.iter().map(|t| t.w as u64 * t.h as u64).sum()
}
