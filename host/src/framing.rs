//! Which part of a render to make: a crop window of the image (`--crop X0,Y0,X1,Y1`) and
//! a range of a camera path's frames (`--frames A..B`). A cropped image has the window's
//! size and the very pixels the whole image has there; a frame keeps its number in the
//! path (`orbit_0005.png`).

use anyhow::{bail, Context};
use magg_core::subscreen::Subscreen;
use std::ops::Range;

/// The crop and frame flags of `render`.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct FramingArgs {
    /// Render only this window of the image, in pixels: X0,Y0,X1,Y1 (X1, Y1 exclusive,
    /// within --width and --height). The image written is the window, with the same
    /// pixels as the whole render has there.
    #[arg(long, value_name = "X0,Y0,X1,Y1")]
    pub crop: Option<String>,
    /// Render only frames A..B of a camera path (B exclusive; A.. to the end, ..B from
    /// the start, or one frame N). Output files keep the frames' numbers.
    #[arg(long, value_name = "A..B")]
    pub frames: Option<String>,
}

impl FramingArgs {
    /// The crop window, checked against the image size.
    pub fn crop(&self, width: u32, height: u32) -> anyhow::Result<Option<Subscreen>> {
        let Some(text) = &self.crop else { return Ok(None) };
        let n: Vec<u32> = text
            .split(',')
            .map(|v| v.trim().parse::<u32>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("--crop {text}: expected four pixel numbers X0,Y0,X1,Y1"))?;
        let [x0, y0, x1, y1] = n[..] else { bail!("--crop {text}: expected four pixel numbers X0,Y0,X1,Y1") };
        if x0 >= x1 || y0 >= y1 {
            bail!("--crop {text}: the window is empty (X0 < X1 and Y0 < Y1 are needed)");
        }
        if x1 > width || y1 > height {
            bail!("--crop {text}: the window leaves the {width} x {height} image");
        }
        Ok(Some(Subscreen { x: x0, y: y0, w: x1 - x0, h: y1 - y0 }))
    }

    /// The frames to render of a path of `count` frames.
    pub fn frames(&self, count: usize) -> anyhow::Result<Range<usize>> {
        let Some(text) = &self.frames else { return Ok(0..count) };
        let num = |s: &str, default: usize| -> anyhow::Result<usize> {
            if s.trim().is_empty() {
                return Ok(default);
            }
            s.trim().parse().with_context(|| format!("--frames {text}: {s:?} is not a frame number"))
        };
        let range = match text.split_once("..") {
            Some((a, b)) => num(a, 0)?..num(b, count)?,
            None => {
                let n = num(text, 0)?;
                n..n + 1
            }
        };
        if range.start >= range.end || range.end > count {
            bail!("--frames {text}: not a non-empty range of the {count} frames 0..{count}");
        }
        Ok(range)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(crop: Option<&str>, frames: Option<&str>) -> FramingArgs {
        FramingArgs { crop: crop.map(String::from), frames: frames.map(String::from) }
    }

    #[test]
    fn crops_are_windows_inside_the_image() {
        assert_eq!(args(None, None).crop(10, 10).unwrap(), None);
        assert_eq!(args(Some("2,3,7,10"), None).crop(10, 10).unwrap(), Some(Subscreen { x: 2, y: 3, w: 5, h: 7 }));
        for bad in ["1,2,3", "a,b,c,d", "5,5,5,6", "0,0,11,5", "-1,0,3,3"] {
            assert!(args(Some(bad), None).crop(10, 10).is_err(), "{bad}");
        }
    }

    #[test]
    fn frame_ranges_stay_inside_the_path() {
        assert_eq!(args(None, None).frames(24).unwrap(), 0..24);
        assert_eq!(args(None, Some("3..7")).frames(24).unwrap(), 3..7);
        assert_eq!(args(None, Some("20..")).frames(24).unwrap(), 20..24);
        assert_eq!(args(None, Some("..2")).frames(24).unwrap(), 0..2);
        assert_eq!(args(None, Some("5")).frames(24).unwrap(), 5..6);
        for bad in ["7..3", "0..25", "x..2", "24"] {
            assert!(args(None, Some(bad)).frames(24).is_err(), "{bad}");
        }
    }
}
