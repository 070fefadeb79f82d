//! The light pass's unit of work (paper §3.2, §4.4): a pair of a light source and an
//! element, and its id.
//!
//! Pairs are numbered light-major over the scene's light sources (the point lights, then
//! the emitting elements, [`crate::header::SceneHeader::light_sources`]): pair id
//! `light * elements + element`. The id is what forks queue, lease, steal and key their
//! exactly-once ledger by, and what travels on the wire; [`Pair`] is what it stands for.
//!
//! ```
//! use magg_core::pair::Pair;
//! let p = Pair::new(2, 7);
//! assert_eq!(p.id(10), 27);
//! assert_eq!(Pair::from_id(27, 10), p);
//! assert_eq!(Pair::element_of(27, 10), 7);
//! ```

/// A (light source, element) pair: the light's rays cast onto the element.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Pair {
    /// The light source: a point light's index, or `lights + k` for emitting element `k`.
    pub light: u32,
    /// The receiving element.
    pub element: u32,
}

impl Pair {
    /// The pair of `light` and `element`.
    pub const fn new(light: u32, element: u32) -> Pair {
        Pair { light, element }
    }

    /// Its id in a scene of `elements` elements.
    pub const fn id(self, elements: u32) -> u64 {
        self.light as u64 * elements as u64 + self.element as u64
    }

    /// The pair of id `id` in a scene of `elements` elements (more than zero; an id in
    /// range, `id < light_sources * elements`, gives a light that fits a `u32`).
    pub const fn from_id(id: u64, elements: u32) -> Pair {
        Pair { light: (id / elements as u64) as u32, element: Pair::element_of(id, elements) }
    }

    /// The element of pair `id` in a scene of `elements` elements (more than zero).
    pub const fn element_of(id: u64, elements: u32) -> u32 {
        (id % elements as u64) as u32
    }

    /// The light of pair `id` in a scene of `elements` elements (more than zero), not
    /// narrowed: an id out of range may name a light past `u32`.
    pub const fn light_of(id: u64, elements: u32) -> u64 {
        id / elements as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_light_major_and_decode_back() {
        let elements = 5;
        let ids: Vec<u64> = (0..3).flat_map(|l| (0..elements).map(move |e| Pair::new(l, e).id(elements))).collect();
        assert_eq!(ids, (0..15).collect::<Vec<_>>());
        for id in 0..15 {
            let p = Pair::from_id(id, elements);
            assert_eq!(p.id(elements), id);
            assert_eq!((Pair::light_of(id, elements), Pair::element_of(id, elements)), (p.light as u64, p.element));
        }
        let far = Pair::new(u32::MAX, u32::MAX - 1);
        assert_eq!(Pair::from_id(far.id(u32::MAX), u32::MAX), far);
    }
}
