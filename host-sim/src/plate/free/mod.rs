//! The plate on a free slide (no Coulomb friction), in scalar closed form.
//!
//! Without slide friction the plate `(x, v, F, q)` is linear and time-invariant under the
//! segment's target `F*`, and the part does not act back on it. With `φ = F − F*` decaying as
//! `φ₀·e^{−ρτ}` (`ρ = 2π·f_c`; `φ ≡ 0` without a current loop) and `r_x = 1/(M·ρ² − c·ρ + k)` the
//! current loop's mode (`c` the slide's damping and viscous friction together),
//!
//! * `x(τ) = X(τ) + r_x·φ(τ)`, `v = X′ − ρ·r_x·φ`, `a = X″ + ρ²·r_x·φ`, `q = ∫X − (r_x/ρ)·φ`,
//!
//! where the slow part `X` obeys `M·X″ + c·X′ + k·X = F*` and is summed as its Taylor series
//! over a chunk of length `L ≤ 1/ω` (`ω = max(√(k/M), c/M)` bounds its rates; the coefficients
//! follow from the equation by a two-term recurrence and are summed until `(ω·L)ⁿ/n!` is below
//! `2⁻⁵⁶`, at most 22 of them). The part slides with constant `u′` or moves with the plate.
//! No matrix exponential is formed: the general solver of [`super::motion`] needs one per
//! regime and a ladder of steps through it.
//!
//! Every event function is `g(τ) = S(τ) + γ·e^{−ρτ}` with `S` a polynomial. Between two zeros of
//! `Q = ρ·S + S′`, `H = e^{ρτ}·g` (`H′ = e^{ρτ}·Q`) is monotone, so `g` has at most one zero
//! there, bracketed by its signs at the ends and refined by Newton's steps ([`crate::plate::roots`]) inside the bracket to
//! a few units in the last place (a turning point, where only the position matters and it is
//! stationary, to 10⁻⁹ of the time). `Q` has no zero where its line `q₀ + q₁·τ` keeps its sign
//! to the chunk's end by more than the bound of its other terms (which grow as `τ²`), and is
//! monotone where its slope's constant outweighs the others' bound over the chunk; then its
//! one zero is found only if `H`'s extremum there may reach zero. Else its zeros are bracketed
//! through its derivatives: `Q″` combines the slow part's two modes only (the line and the
//! current loop's mode drop out), which turn by at most `ω·L ≤ 1` radian over the chunk, so it
//! has at most one zero there, `Q′` at most two and `Q` at most three ([`chunk`]'s search).
//!
//! The plate does not feel the part, so a chunk of its motion serves every contact the part
//! passes through within it, and runs on across segments that hold the command ([`FreeSolver`]).
//! A chunk's turning points and end-stop contacts are sought only where a bound of its reach
//! may pass the peak so far or the stop ([`chunk`]), and its end is a linear map of
//! its slow start, kept for the chunk lengths a periodic drive repeats ([`end_maps`]).

mod chunk;
mod end_maps;
mod slide;
mod solver;
#[cfg(test)]
mod tests;

pub use solver::FreeSolver;
