//! What a pair's rays did: where their flux went ([`LrtTally`]), their deposits as the
//! rays made them ([`RawPair`]), and binned to leaf elements in fixed point
//! ([`PairResult`]).

use crate::color::Rgb;
use crate::fixed::Fixed;

/// Where the flux of a pair went. All fields in W per channel.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct LrtTally {
    /// Flux of primary rays that reached their element (`I * Omega` when unoccluded).
    pub reached: Rgb,
    /// Flux of primary rays blocked before their element.
    pub occluded: Rgb,
    /// Absorbed at surfaces (`1 - diffuse - mirror - transmit`).
    pub absorbed: Rgb,
    /// Diffusely reflected but not followed (no diffuse bounce left): the paper's end of
    /// a light path, shown in VRT through the element's energy.
    pub diffuse_end: Rgb,
    /// Carried by secondary rays that left the scene.
    pub escaped: Rgb,
    /// Carried by rays stopped by a depth limit or the minimum-flux cut.
    pub cut: Rgb,
}

impl LrtTally {
    /// Sum of two tallies.
    pub fn add(self, o: LrtTally) -> LrtTally {
        LrtTally {
            reached: self.reached.add(o.reached),
            occluded: self.occluded.add(o.occluded),
            absorbed: self.absorbed.add(o.absorbed),
            diffuse_end: self.diffuse_end.add(o.diffuse_end),
            escaped: self.escaped.add(o.escaped),
            cut: self.cut.add(o.cut),
        }
    }
}

/// The deposits and tally of one pair.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PairResult {
    /// (element id, flux) sorted by element id, one entry per element.
    pub deposits: Vec<(u32, Fixed)>,
    /// Where the flux went.
    pub tally: LrtTally,
}

/// A deposit as a pair's rays make it, before refinement's leaves are looked up: on an
/// element itself (the pair's own target), or at local coordinates `w` within a lattice
/// element, which refinement may have split (the leaf under `w` takes it). A pair's raw
/// deposits stay the same while other elements are split, so refinement's pilot passes
/// trace a pair once and bin its deposits again at each level ([`bin`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RawDeposit {
    /// On this element.
    On(u32, Rgb),
    /// On the leaf under local coordinates `w` of lattice element `element`.
    Under {
        /// The lattice element (on the face the ray arrived at).
        element: u32,
        /// Local (barycentric) coordinates within it.
        w: [f64; 3],
        /// The flux.
        flux: Rgb,
    },
}

/// A pair's raw deposits, in the order its rays made them, and its tally.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RawPair {
    /// The deposits, in generation order.
    pub deposits: Vec<RawDeposit>,
    /// Where the flux went.
    pub tally: LrtTally,
}
