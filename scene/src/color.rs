//! The colour type: an RGB triple of radiometric quantities.
//!
//! glam has no colour type, so this one is ours. Channels are `f64` while computed and
//! `f32` when stored in blocks and frames.

/// An RGB triple (radiometric quantity per colour channel).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Rgb(pub [f64; 3]);

impl Rgb {
    /// Black.
    pub const BLACK: Rgb = Rgb([0.0; 3]);
    /// One in every channel: what multiplies a colour without changing it (exactly: x * 1.0
    /// is x).
    pub const WHITE: Rgb = Rgb([1.0; 3]);
    /// Builds a colour from its channels.
    pub const fn new(r: f64, g: f64, b: f64) -> Self {
        Rgb([r, g, b])
    }
    /// The same value in every channel.
    pub const fn splat(v: f64) -> Self {
        Rgb([v, v, v])
    }
    /// Largest channel.
    pub fn max_channel(self) -> f64 {
        self.0[0].max(self.0[1]).max(self.0[2])
    }
    /// True when every channel is zero.
    pub fn is_black(self) -> bool {
        self.0 == [0.0; 3]
    }
    /// Mean of the channels.
    pub fn mean(self) -> f64 {
        (self.0[0] + self.0[1] + self.0[2]) / 3.0
    }
    /// Rec. 709 luminance.
    pub fn luminance(self) -> f64 {
        0.2126 * self.0[0] + 0.7152 * self.0[1] + 0.0722 * self.0[2]
    }
    /// Channel-wise product.
    pub fn mul(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] * o.0[0], self.0[1] * o.0[1], self.0[2] * o.0[2]])
    }
    /// Scale every channel.
    pub fn scale(self, s: f64) -> Rgb {
        Rgb([self.0[0] * s, self.0[1] * s, self.0[2] * s])
    }
    /// Channel-wise sum.
    pub fn add(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
    /// True when every channel is finite.
    pub fn is_finite(self) -> bool {
        self.0.iter().all(|c| c.is_finite())
    }
}
