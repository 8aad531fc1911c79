//! The ends of a free slide's chunks as linear maps of their slow start, kept for the chunk
//! lengths a periodic drive repeats.

use crate::plate::roots::{horner, weighted};

use super::slide::{FreeSlide, Poly, FALLING, INVERSE};

/// A chunk's end as a linear map of its slow part's start `(X(0), X′(0), F*)`: `X`, `X′` and
/// `∫X` at its length `L`, and the current loop's decay `e^{−ρL}` over it; with the bound of
/// the change in `X″` over the chunk per unit of each, `Σ_{n≥1} |X″_n|·Lⁿ` of its basis.
#[derive(Debug, Clone, Copy, Default)]
pub struct EndMap {
    pub length_s: f64,
    pub position: [f64; 3],
    pub velocity: [f64; 3],
    pub integral: [f64; 3],
    pub decay: f64,
    pub accel_spread: [f64; 3],
}

/// The end maps of the chunk lengths a periodic drive repeats: a length's map is made the
/// second time it is met within the last [`ENDS`] new lengths, and kept for the last [`ENDS`]
/// made.
#[derive(Debug, Clone, Copy, Default)]
pub struct Ends {
    maps: [EndMap; ENDS],
    made: usize,
    met: [f64; ENDS],
    newest: usize,
}

/// Chunk lengths whose end maps are kept.
const ENDS: usize = 4;

impl Ends {
    /// The end map for chunks of `length_s` with `terms` Taylor terms, if the length has come
    /// before.
    pub fn get(&mut self, free: &FreeSlide, length_s: f64, terms: usize) -> Option<&EndMap> {
        let kept = self.made.min(ENDS);
        if let Some(i) = self.maps[..kept]
            .iter()
            .position(|map| map.length_s == length_s)
        {
            return Some(&self.maps[i]);
        }
        if !self.met.contains(&length_s) {
            self.met[self.newest % ENDS] = length_s;
            self.newest += 1;
            return None;
        }
        let at = |p: &Poly| horner(&p[..terms], length_s);
        let slope = |p: &Poly| weighted(&p[1..terms], &FALLING[1][1..], length_s);
        let integral = |p: &Poly| length_s * weighted(&p[..terms], &INVERSE[1..], length_s);
        let accel_spread = |p: &Poly| {
            let accel = p[3..terms].iter().zip(&FALLING[2][3..]);
            length_s
                * accel
                    .rev()
                    .fold(0.0, |sum, (c, k)| sum * length_s + (k * c).abs())
        };
        let map = &mut self.maps[self.made % ENDS];
        self.made += 1;
        *map = EndMap {
            length_s,
            position: free.basis.each_ref().map(at),
            velocity: free.basis.each_ref().map(slope),
            integral: free.basis.each_ref().map(integral),
            decay: (-free.lag_per_s * length_s).exp(),
            accel_spread: free.basis.each_ref().map(accel_spread),
        };
        Some(map)
    }
}
