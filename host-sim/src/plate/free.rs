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
//! there, bracketed by its signs at the ends and refined by Newton's steps inside the bracket to
//! a few units in the last place (a turning point, where only the position matters and it is
//! stationary, to 10⁻⁹ of the time). `Q` has no zero where its line `q₀ + q₁·τ` keeps its sign
//! to the chunk's end by more than the bound of its other terms (which grow as `τ²`), and is
//! monotone where its slope's constant outweighs the others' bound over the chunk; then its
//! one zero is found only if `H`'s extremum there may reach zero. Else its zeros are bracketed
//! through its derivatives: `Q″` combines the slow part's two modes only (the line and the
//! current loop's mode drop out), which turn by at most `ω·L ≤ 1` radian over the chunk, so it
//! has at most one zero there, `Q′` at most two and `Q` at most three.
//!
//! The plate does not feel the part, so a chunk of its motion serves every contact the part
//! passes through within it, and runs on across segments that hold the command ([`Course`]).
//! A chunk's turning points and end-stop contacts are sought only where a bound of its reach
//! may pass the peak so far or the stop (`Chunk::reach_m`), and its end is a linear map of
//! its slow start, kept for the chunk lengths a periodic drive repeats (`Ends`).

use super::linear::{State, F, P, Q, U, V, X};
use super::motion::{Event, Model, Part, Slide};

/// Taylor coefficients summed for the slow part over a chunk of at most `1/ω`.
const TERMS: usize = 22;

/// The last Taylor term summed is below this, relative to the slow part's scale.
const TAIL: f64 = f64::EPSILON / 16.0;

/// Zeros of `Q` on a chunk at most (one of `Q″`, two of `Q′`).
const MAX_ZEROS: usize = 3;

type Poly = [f64; TERMS];

/// `n·(n − 1)·…·(n − d + 1)` for `d ≤ 3`, `n < TERMS`: the weight of `X_n` in the Taylor
/// coefficient of `τ^(n−d)` in `X^(d)`.
const FALLING: [[f64; TERMS]; 4] = {
    let mut out = [[0.0; TERMS]; 4];
    let mut n = 0;
    while n < TERMS {
        let mut d = 0;
        let mut weight = 1.0;
        while d < 4 {
            out[d][n] = weight;
            weight *= n as f64 - d as f64;
            d += 1;
        }
        n += 1;
    }
    out
};

/// `1/n` for `n < TERMS + 1` (`1/0` left at 0).
const INVERSE: [f64; TERMS + 1] = {
    let mut out = [0.0; TERMS + 1];
    let mut n = 1;
    while n <= TERMS {
        out[n] = 1.0 / n as f64;
        n += 1;
    }
    out
};

/// The plate on a free slide and its part: a [`Model`] with what the scalar solution adds.
#[derive(Debug, Clone, Copy)]
pub struct FreeSlide {
    model: Model,
    /// `ρ`, 0 without a current loop.
    lag_per_s: f64,
    /// `r_x`: the plate's position per newton of `φ` in the current loop's mode.
    mode_m_per_n: f64,
    /// Taylor coefficients of `X` from `X(0) = 1`, from `X′(0) = 1` and for `F* = 1`, the
    /// others 0: `X` is their sum weighted by its start and the target.
    basis: [Poly; 3],
    longest_chunk_s: f64,
    /// `reach_limits[n]`: the reach `ω·L` from which `n` terms are too few, `(tol·(n−1)!)^{1/(n−1)}`
    /// with `tol` = [`TAIL`] (`n ≥ 4`).
    reach_limits: [f64; TERMS],
}

impl FreeSlide {
    /// The free slide of `model`; `None` if the slide has Coulomb friction, or if the current
    /// loop's rate is one of the slide's own (the mode cannot be split off).
    pub fn new(model: &Model) -> Option<FreeSlide> {
        if model.params.coulomb_friction_n != 0.0 {
            return None;
        }
        // The plate's equation, `X″ = a_x·X + a_v·X′ + a_F·F`, as the model has it.
        let row = model.plate_accel_row(Slide::Free);
        let (a_x, a_v, a_f) = (row[X], row[V], row[F]);
        let (lag_per_s, mode_m_per_n) = match model.lag_per_s {
            Some(rho) => {
                // `r_x·(ρ² + a_v·ρ − a_x) = a_F`: zero where `−ρ` is one of the slide's rates.
                let stiffness = rho * rho + a_v * rho - a_x;
                let scale = rho * rho + a_v.abs() * rho + a_x.abs();
                if stiffness.abs() <= 1e-9 * scale {
                    return None;
                }
                (rho, a_f / stiffness)
            }
            None => (0.0, 0.0),
        };
        let series = |x0: f64, v0: f64, force_n: f64| {
            let mut x = [0.0; TERMS];
            x[0] = x0;
            x[1] = v0;
            x[2] = 0.5 * (a_x * x0 + a_v * v0 + a_f * force_n);
            for n in 1..TERMS - 2 {
                x[n + 2] = (a_x * x[n] + a_v * (n + 1) as f64 * x[n + 1])
                    * INVERSE[n + 1]
                    * INVERSE[n + 2];
            }
            x
        };
        Some(FreeSlide {
            model: *model,
            basis: [
                series(1.0, 0.0, 0.0),
                series(0.0, 1.0, 0.0),
                series(0.0, 0.0, 1.0),
            ],
            lag_per_s,
            mode_m_per_n,
            longest_chunk_s: if model.slow_per_s > 0.0 {
                1.0 / model.slow_per_s
            } else {
                f64::INFINITY
            },
            reach_limits: core::array::from_fn(|n| {
                let below = n.max(2) as i32 - 1;
                let factorial: f64 = (1..=below).map(f64::from).product();
                (TAIL * factorial).powf(1.0 / f64::from(below))
            }),
        })
    }

    /// The first event within `duration_s` of the state `z0` under the drive target `target_n`
    /// with the part in contact `part`, with its time, and the state then (at `duration_s` if no
    /// event comes first); `peak_m` is raised to the plate's distance from the centre at its
    /// turning points before it. The same answer as [`Model::next_event`] on the free slide.
    pub fn next_event(
        &self,
        part: Part,
        target_n: f64,
        z0: &State,
        duration_s: f64,
        peak_m: &mut f64,
    ) -> (Option<(Event, f64)>, State) {
        let mut course = Course::default();
        course.begin(target_n, duration_s, duration_s);
        course.next_event(self, part, z0, 0.0, peak_m)
    }
}

/// The plate through one segment on a free slide, and the part on it, event by event. The plate
/// does not feel the part, so a chunk of its motion, with its turning points and its first
/// contact with an end stop, serves every contact the part passes through within it: after the
/// part's event the course goes on in the same chunk. Where the next segment holds the target,
/// chunks run on over it, and the course goes on across the boundary.
#[derive(Debug, Clone, Default)]
pub struct Course {
    target_n: f64,
    duration_s: f64,
    /// How long the target holds from the segment's start: its duration or more.
    holds_s: f64,
    /// The current chunk, if `valid`.
    chunk: Chunk,
    valid: bool,
    /// Where the last event or the segment's end left the course.
    resume: Option<Resume>,
    /// The ends of chunks of recent lengths.
    ends: Ends,
}

/// A chunk's end as a linear map of its slow part's start `(X(0), X′(0), F*)`: `X`, `X′` and
/// `∫X` at its length `L`, and the current loop's decay `e^{−ρL}` over it; with the bound of
/// the change in `X″` over the chunk per unit of each, `Σ_{n≥1} |X″_n|·Lⁿ` of its basis.
#[derive(Debug, Clone, Copy, Default)]
struct EndMap {
    length_s: f64,
    position: [f64; 3],
    velocity: [f64; 3],
    integral: [f64; 3],
    decay: f64,
    accel_spread: [f64; 3],
}

/// The end maps of the chunk lengths a periodic drive repeats: a length's map is made the
/// second time it is met within the last [`ENDS`] new lengths, and kept for the last [`ENDS`]
/// made; all are dropped if the free slide is another.
#[derive(Debug, Clone, Copy, Default)]
struct Ends {
    maps: [EndMap; ENDS],
    made: usize,
    met: [f64; ENDS],
    newest: usize,
    /// The free slide's `ρ` and `X″(0)` per unit of `X(0)`, `X′(0)` and `F*`, which fix its
    /// motion.
    slide: [f64; 4],
}

/// Chunk lengths whose end maps are kept.
const ENDS: usize = 4;

impl Ends {
    /// The end map for chunks of `length_s` with `terms` Taylor terms, if the length has come
    /// before.
    fn get(&mut self, free: &FreeSlide, length_s: f64, terms: usize) -> Option<&EndMap> {
        let [from_x, from_v, from_force] = &free.basis;
        let slide = [free.lag_per_s, from_x[2], from_v[2], from_force[2]];
        if slide != self.slide {
            *self = Ends {
                slide,
                ..Ends::default()
            };
        }
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

/// An event's or a segment's end's place in its chunk, to go on from if the next call starts
/// there.
#[derive(Debug, Clone, Copy)]
struct Resume {
    /// The segment's time of the event, as the caller adds it up (0 for the next segment).
    offset_s: f64,
    /// Its time in the chunk.
    in_chunk_s: f64,
    /// The state returned there.
    state: State,
    /// At a segment's end inside the chunk, what lies ahead of it there.
    ahead: Option<Ahead>,
}

/// The part's first event in the chunk after a segment's end inside it (`None` up to the
/// chunk's end), for the contact it had there.
#[derive(Debug, Clone, Copy)]
struct Ahead {
    part: Part,
    first: Option<(Event, f64)>,
}

fn plate_of(z: &State) -> [f64; 4] {
    [z[X], z[V], z[F], z[Q]]
}

impl Course {
    /// Starts a segment of `duration_s` under the drive target `target_n`, which holds for
    /// `holds_s ≥ duration_s` (into the segments after it). Where the last segment held the same
    /// target and ended inside its chunk, the course goes on in that chunk.
    pub fn begin(&mut self, target_n: f64, duration_s: f64, holds_s: f64) {
        let goes_on = self.valid
            && target_n == self.target_n
            && self.resume.is_some_and(|resume| resume.ahead.is_some());
        if goes_on {
            if let Some(resume) = self.resume.as_mut() {
                resume.offset_s = 0.0;
            }
        } else {
            self.valid = false;
            self.resume = None;
        }
        self.target_n = target_n;
        self.duration_s = duration_s;
        self.holds_s = holds_s.max(duration_s);
    }

    /// The first event from the state `z` at `offset_s` into the segment, with the part in
    /// contact `part`, as [`FreeSlide::next_event`] over the rest of the segment: its time from
    /// `offset_s`, and the state then. Where `z` is the state this course returned at its last
    /// event, with only the part changed since, and `offset_s` that event's time, it goes on in
    /// that event's chunk. The turning points of a chunk whose reach stays below `peak_m` are
    /// not sought: they could not raise it.
    pub fn next_event(
        &mut self,
        free: &FreeSlide,
        part: Part,
        z: &State,
        offset_s: f64,
        peak_m: &mut f64,
    ) -> (Option<(Event, f64)>, State) {
        let duration_s = (self.duration_s - offset_s).max(0.0);
        let holds_s = (self.holds_s - offset_s).max(0.0);
        let mut z = *z;
        // The call's time of the chunk's start, the chunk's time of `z`, and the part's first
        // event after it if known.
        let (mut start_s, mut from_s, mut ahead) = match self.resume.take() {
            Some(resume)
                if self.valid
                    && resume.offset_s == offset_s
                    && plate_of(&resume.state) == plate_of(&z) =>
            {
                // The part's event ahead holds if nothing has changed since.
                let ahead = resume
                    .ahead
                    .filter(|ahead| resume.state == z && ahead.part == part);
                (-resume.in_chunk_s, resume.in_chunk_s, ahead)
            }
            _ => {
                self.valid = false;
                (0.0, 0.0, None)
            }
        };
        loop {
            if !self.valid {
                if duration_s - start_s <= 0.0 {
                    return (None, z);
                }
                let length_s = free.longest_chunk_s.min(holds_s - start_s);
                self.chunk
                    .start(free, self.target_n, &z, length_s, *peak_m, &mut self.ends);
                self.valid = true;
                from_s = 0.0;
            }
            let chunk = &mut self.chunk;
            let first = match ahead.take() {
                Some(ahead) => ahead.first,
                None => chunk.part_event(free, part, &z, from_s),
            };
            // The segment's end in the chunk's time, if it comes before the chunk's.
            let length_s = chunk.length_s;
            let end_s = duration_s - start_s;
            let until_s = end_s.min(length_s);
            for &t in chunk.turns.as_slice() {
                if t > from_s && t <= until_s && first.is_none_or(|(_, at)| t <= at) {
                    *peak_m = peak_m.max(chunk.position(t).abs());
                }
            }
            if let Some((event, t)) = first.filter(|&(_, t)| t <= until_s) {
                let state = chunk.state(free, t, part, &z, from_s);
                let elapsed_s = start_s + t;
                self.resume = Some(Resume {
                    offset_s: offset_s + elapsed_s,
                    in_chunk_s: t,
                    state,
                    ahead: None,
                });
                return (Some((event, elapsed_s)), state);
            }
            if end_s < length_s {
                let state = chunk.state(free, end_s, part, &z, from_s);
                self.resume = Some(Resume {
                    offset_s: offset_s + duration_s,
                    in_chunk_s: end_s,
                    state,
                    ahead: Some(Ahead { part, first }),
                });
                return (None, state);
            }
            z = chunk.state(free, length_s, part, &z, from_s);
            self.valid = false;
            if end_s <= length_s {
                return (None, z);
            }
            start_s += length_s;
        }
    }
}

/// A few sorted times.
#[derive(Debug, Clone, Copy, Default)]
struct Times {
    len: usize,
    at: [f64; MAX_ZEROS + 2],
}

impl Times {
    fn push(&mut self, t: f64) {
        if self.len < self.at.len() {
            self.at[self.len] = t;
            self.len += 1;
        }
    }

    fn as_slice(&self) -> &[f64] {
        &self.at[..self.len]
    }
}

/// An event function `g(τ) = w·X^(d)(τ) + c + s·τ + γ·e^{−ρτ}`: a weighted derivative of the
/// slow position (`d = 0, 1, 2`: position, velocity, acceleration), a line, and the current
/// loop's mode. `Q = ρ·S + S′ = w·(ρ·X^(d) + X^(d+1)) + ρ·c + s + ρ·s·τ`.
#[derive(Debug, Clone, Copy)]
struct Function {
    order: usize,
    /// `ρ·X^(d) + X^(d+1)` over the chunk.
    mode: Mode,
    weight: f64,
    constant: f64,
    slope: f64,
    fast: f64,
    /// The time from which it is watched.
    from: f64,
    /// `g(from)` from the state itself, exactly zero where the regime was entered on its
    /// boundary.
    start: f64,
    /// `g` at the chunk's end.
    end: f64,
}

/// `ρ·X^(d) + X^(d+1)` over a chunk: its order `d`, its two lowest Taylor coefficients, how
/// many it has, and the bounds of its terms from `τ²` on over the chunk, `Σ_{m≥2} |c_m|·L^m`
/// and `Σ_{m≥2} m·|c_m|·L^{m−1}`, which bound `Q`'s and `Q′`'s variation for every function on
/// this derivative.
#[derive(Debug, Clone, Copy)]
struct Mode {
    order: usize,
    low: [f64; 2],
    len: usize,
    tail: f64,
    slope_tail: f64,
}

/// The plate's motion from a state, over one chunk, with its turning points and its first
/// contact with an end stop there.
#[derive(Debug, Clone, Default)]
struct Chunk {
    target_n: f64,
    /// `ρ` and `r_x` of the free slide.
    lag_per_s: f64,
    mode_m_per_n: f64,
    /// `φ₀`.
    phi_n: f64,
    /// Taylor coefficients of the slow position `X` and of its first three derivatives:
    /// `series[d][m]` is the coefficient of `τ^m` in `X^(d)`.
    series: [Poly; 4],
    /// `∫X` at the start.
    q0: f64,
    /// The chunk's length `L` and the plate's `(x, v)` then.
    length_s: f64,
    end: (f64, f64),
    /// `∫X` over the chunk and a bound of the change in `X″` over it, if its end came from a
    /// map.
    end_integral: Option<f64>,
    accel_spread: Option<f64>,
    /// `φ(L)`.
    phi_end_n: f64,
    /// Taylor coefficients summed: the first `n` with `(ω·L)ⁿ/n!` below `2⁻⁵⁶` for the chunk's
    /// length `L`, at least 4 (a plate without spring or damping is a cubic).
    terms: usize,
    /// `ρ·X^(d) + X^(d+1)` for `d = 0, 1, 2`, as the functions watched need them.
    modes: [Option<Mode>; 3],
    /// The plate's turning points in `(0, L]`.
    turns: Times,
    /// The first time the plate reaches an end stop in `[0, L]`.
    end_stop: Option<f64>,
}

impl Chunk {
    /// Makes this the chunk of `length_s` from the state `z0`, with its turning points if the
    /// plate may pass `peak_m` in it; its end from the map in `ends` if its length has one.
    /// Out of line, as [`Chunk::part_event`]: inlined, they crowd the course's loop (7 % more
    /// instructions a cycle).
    #[inline(never)]
    fn start(
        &mut self,
        free: &FreeSlide,
        target_n: f64,
        z0: &State,
        length_s: f64,
        peak_m: f64,
        ends: &mut Ends,
    ) {
        let rho = free.lag_per_s;
        let r_x = free.mode_m_per_n;
        let phi_n = if rho > 0.0 { z0[F] - target_n } else { 0.0 };
        // `ω·L ≤ 1`, so `(ω·L)^(n−1)/(n−1)!` falls with `n`.
        let reach = free.model.slow_per_s * length_s;
        let mut terms = 4;
        while terms < TERMS && reach >= free.reach_limits[terms] {
            terms += 1;
        }
        self.target_n = target_n;
        self.lag_per_s = rho;
        self.mode_m_per_n = r_x;
        self.phi_n = phi_n;
        self.q0 = if rho > 0.0 {
            z0[Q] + r_x / rho * phi_n
        } else {
            z0[Q]
        };
        self.length_s = length_s;
        let map = ends.get(free, length_s, terms).copied();
        self.phi_end_n = match map {
            _ if phi_n == 0.0 => 0.0,
            Some(map) => phi_n * map.decay,
            None => phi_n * (-rho * length_s).exp(),
        };
        self.terms = terms;
        self.modes = [None; 3];
        self.end_stop = None;
        let x0 = z0[X] - r_x * phi_n;
        let v0 = z0[V] + rho * r_x * phi_n;
        let [from_x, from_v, from_force] = &free.basis;
        let [position, velocity, accel, jerk] = &mut self.series;
        for (n, c) in position.iter_mut().enumerate() {
            *c = x0 * from_x[n] + v0 * from_v[n] + target_n * from_force[n];
        }
        for (d, derivative) in [velocity, accel, jerk].into_iter().enumerate() {
            let d = d + 1;
            let (low, high) = derivative.split_at_mut(TERMS - d);
            for ((c, p), k) in low.iter_mut().zip(&position[d..]).zip(&FALLING[d][d..]) {
                *c = k * p;
            }
            high.fill(0.0);
        }
        self.end = match map {
            Some(map) => {
                let slow = |c: [f64; 3]| c[0] * x0 + c[1] * v0 + c[2] * target_n;
                self.end_integral = Some(slow(map.integral));
                let [x, v, force] = map.accel_spread;
                self.accel_spread = Some(x * x0.abs() + v * v0.abs() + force * target_n.abs());
                (
                    slow(map.position) + self.mode_share(0) * self.phi_end_n,
                    slow(map.velocity) + self.mode_share(1) * self.phi_end_n,
                )
            }
            None => {
                self.end_integral = None;
                self.accel_spread = None;
                let (x, v, _) = self.plate_at(length_s, self.phi_end_n, false);
                (x, v)
            }
        };
        let x_lim = free.model.params.end_stop_m;
        let reach_m = if peak_m > 0.0 || x_lim.is_some() {
            self.reach_m() * (1.0 + REACH_MARGIN)
        } else {
            f64::INFINITY
        };
        self.turns = if reach_m < peak_m {
            Times::default()
        } else {
            let turn = self.function(1, 1.0, 0.0, 0.0, 0.0, z0[V]);
            let pieces = self.pieces(&turn);
            self.sign_changes(&turn, &pieces)
        };
        if let Some(x_lim) = x_lim.filter(|&x_lim| reach_m >= x_lim) {
            for sign in [1.0, -1.0] {
                let stop = self.function(0, -sign, x_lim, 0.0, 0.0, x_lim - sign * z0[X]);
                let pieces = self.pieces(&stop);
                if let Some(t) = self.first_zero(&stop, &pieces) {
                    if self.end_stop.is_none_or(|at| t < at) {
                        self.end_stop = Some(t);
                    }
                }
            }
        }
    }

    /// A bound of the plate's distance from the centre over the chunk: the slow part's from
    /// parabolas through either end with the bounds of its acceleration `X″` (exact where `X″`
    /// keeps a sign: the far side is then at an end), and the current loop's mode's at most
    /// `|r_x·φ₀|`. `X″` strays from its start by at most `Σ_{n≥1} |X″_n|·Lⁿ`, or the map's
    /// bound.
    fn reach_m(&self) -> f64 {
        let length_s = self.length_s;
        let accel = self.derivative(2);
        let spread = self.accel_spread.unwrap_or_else(|| {
            let terms = accel[1..].iter().rev();
            length_s * terms.fold(0.0, |sum, c| sum * length_s + c.abs())
        });
        let (low, high) = (accel[0] - spread, accel[0] + spread);
        let start = (self.series[0][0], self.series[1][0]);
        let end = (
            self.end.0 - self.mode_share(0) * self.phi_end_n,
            self.end.1 - self.mode_share(1) * self.phi_end_n,
        );
        let above = farthest(start, end, high, low, length_s);
        let below = farthest(
            (-start.0, -start.1),
            (-end.0, -end.1),
            -low,
            -high,
            length_s,
        );
        larger(above, below) + (self.mode_share(0) * self.phi_n).abs()
    }

    /// The Taylor coefficients of `X^(d)`, `d ≤ 3`.
    fn derivative(&self, d: usize) -> &[f64] {
        &self.series[d][..self.terms - d]
    }

    /// `X^(d)(τ)` and `X^(d+1)(τ)`, `d ≤ 2`, summed side by side (`X^(d+1)` to the length of
    /// `X^(d)`: its coefficient after its last is 0).
    fn derivative_pair(&self, d: usize, t: f64) -> (f64, f64) {
        let len = self.terms - d;
        horner_pair(&self.series[d][..len], &self.series[d + 1][..len], t)
    }

    /// `φ(τ)`.
    fn phi(&self, t: f64) -> f64 {
        if self.phi_n == 0.0 {
            0.0
        } else if t == self.length_s {
            self.phi_end_n
        } else {
            self.phi_n * (-self.lag_per_s * t).exp()
        }
    }

    /// The current loop's mode's part of `x^(d)` per newton of `φ`: `r_x·(−ρ)^d`, `d ≤ 2`.
    fn mode_share(&self, order: usize) -> f64 {
        let rho = self.lag_per_s;
        self.mode_m_per_n
            * match order {
                0 => 1.0,
                1 => -rho,
                _ => rho * rho,
            }
    }

    /// The plate's position at `τ`.
    fn position(&self, t: f64) -> f64 {
        horner(self.derivative(0), t) + self.mode_share(0) * self.phi(t)
    }

    /// The plate's `(x, v, a)` at `τ`, where `φ` is `phi`; `a` only if `accel` (else 0).
    fn plate_at(&self, t: f64, phi: f64, accel: bool) -> (f64, f64, f64) {
        let (x, v) = self.derivative_pair(0, t);
        let a = if accel {
            horner(self.derivative(2), t)
        } else {
            0.0
        };
        (
            x + self.mode_share(0) * phi,
            v + self.mode_share(1) * phi,
            a + self.mode_share(2) * phi,
        )
    }

    /// The whole state at `τ`, from the state `z` at `from` with the part in contact `part`.
    fn state(&self, free: &FreeSlide, t: f64, part: Part, z: &State, from: f64) -> State {
        let phi = self.phi(t);
        let (x, v) = if t == self.length_s {
            self.end
        } else {
            let (x, v, _) = self.plate_at(t, phi, false);
            (x, v)
        };
        let integral = match self.end_integral {
            Some(integral) if t == self.length_s => integral,
            _ => t * weighted(self.derivative(0), &INVERSE[1..], t),
        };
        let mut q = self.q0 + integral;
        if self.lag_per_s > 0.0 {
            q -= self.mode_m_per_n / self.lag_per_s * phi;
        }
        let mut out = *z;
        out[X] = x;
        out[V] = v;
        out[F] = self.target_n + phi;
        out[Q] = q;
        match part {
            Part::Sliding(sigma) => {
                let accel = free.model.sliding_part_accel_mps2(sigma);
                let dt = t - from;
                out[P] = z[P] + dt * (z[U] + 0.5 * accel * dt);
                out[U] = z[U] + accel * dt;
            }
            Part::Stuck => {
                out[P] = z[P] + (x - z[X]);
                out[U] = v;
            }
        }
        out
    }

    /// The function `w·X^(d) + c + s·τ` with the current loop's part of `x^(d)` weighted alike,
    /// watched from `from`, where it is `start`.
    fn function(
        &mut self,
        order: usize,
        weight: f64,
        constant: f64,
        slope: f64,
        from: f64,
        start: f64,
    ) -> Function {
        let mode = match self.modes[order] {
            Some(mode) => mode,
            None => *self.modes[order].insert(self.mode(order)),
        };
        let fast = weight * self.phi_n * self.mode_share(order);
        let at_end = match order {
            0 => self.end.0,
            1 => self.end.1,
            _ => self.plate_at(self.length_s, self.phi_end_n, true).2,
        };
        Function {
            order,
            mode,
            weight,
            constant,
            slope,
            fast,
            from,
            start,
            end: weight * at_end + constant + slope * self.length_s,
        }
    }

    /// The part's first event in `[from, L]` from the state `z` at `from` (or the plate's first
    /// contact with an end stop, if that comes first).
    #[inline(never)]
    fn part_event(
        &mut self,
        free: &FreeSlide,
        part: Part,
        z: &State,
        from: f64,
    ) -> Option<(Event, f64)> {
        let mut first: Option<(Event, f64)> = None;
        match part {
            Part::Sliding(sigma) => {
                let accel = free.model.sliding_part_accel_mps2(sigma);
                let constant = sigma * (z[U] - accel * from);
                let start = -sigma * z[V] + sigma * z[U];
                let meet = self.function(1, -sigma, constant, sigma * accel, from, start);
                let pieces = self.pieces(&meet);
                first = self
                    .first_zero(&meet, &pieces)
                    .map(|t| (Event::PartMeetsPlate, t));
            }
            Part::Stuck => {
                let contact = &free.model.contact;
                let start_accel_mps2 = free.model.plate_accel_mps2(Slide::Free, z);
                for sign in [1.0, -1.0] {
                    let constant = contact.static_accel_mps2() + sign * contact.force_accel_mps2();
                    let start = -sign * start_accel_mps2 + constant;
                    let away = self.function(2, -sign, constant, 0.0, from, start);
                    let pieces = self.pieces(&away);
                    if let Some(t) = self.first_zero(&away, &pieces) {
                        if first.is_none_or(|(_, at)| t < at) {
                            first = Some((Event::PartBreaksAway, t));
                        }
                    }
                }
            }
        }
        if let Some(t) = self.end_stop {
            if t >= from && first.is_none_or(|(_, at)| t < at) {
                first = Some((Event::EndStop, t));
            }
        }
        first
    }

    /// The Taylor coefficient of `τ^m` in `ρ·X^(d) + X^(d+1)`.
    fn mode_coefficient(&self, order: usize, m: usize) -> f64 {
        self.lag_per_s * self.series[order][m] + self.series[order + 1][m]
    }

    /// `ρ·X^(d) + X^(d+1)` over the chunk.
    fn mode(&self, order: usize) -> Mode {
        let length_s = self.length_s;
        let len = self.terms - order;
        // `Σ_{m≥2} |c_m|·L^(m−2)` and `Σ_{m≥2} m·|c_m|·L^(m−2)`, by Horner's scheme.
        let (mut tail, mut slope_tail) = (0.0, 0.0);
        let rho = self.lag_per_s;
        let lower = &self.series[order][2..len];
        let higher = &self.series[order + 1][2..len];
        for ((l, h), m) in lower.iter().zip(higher).zip(&FALLING[1][2..len]).rev() {
            let c = (rho * l + h).abs();
            tail = tail * length_s + c;
            slope_tail = slope_tail * length_s + m * c;
        }
        Mode {
            order,
            low: [
                self.mode_coefficient(order, 0),
                self.mode_coefficient(order, 1),
            ],
            len,
            tail: tail * length_s * length_s,
            slope_tail: slope_tail * length_s,
        }
    }

    /// The Taylor coefficients of `Q = ρ·S + S′` for a function of weight `w` whose `Q` starts
    /// `q0 + q1·τ`, as many as its mode has.
    fn q_poly(&self, w: f64, mode: &Mode, [q0, q1]: [f64; 2]) -> Poly {
        let rho = self.lag_per_s;
        let len = mode.len;
        let lower = &self.series[mode.order][..len];
        let higher = &self.series[mode.order + 1][..len];
        let mut out = [0.0; TERMS];
        for ((c, l), h) in out[..len].iter_mut().zip(lower).zip(higher) {
            *c = w * (rho * l + h);
        }
        out[0] = q0;
        out[1] = q1;
        out
    }

    /// Times `from = t₀ < t₁ < … < L` between which `H = e^{ρτ}·g` is monotone, as far as the
    /// zeros of `g` after `from` need them: where `Q = ρ·S + S′` is monotone, its zero only if
    /// `H`'s extremum there turns towards zero between ends of one sign (or leaves zero from the
    /// start); else every zero of `Q`.
    fn pieces(&self, function: &Function) -> Times {
        let mode = &function.mode;
        let length_s = self.length_s;
        let rho = self.lag_per_s;
        let w = function.weight;
        let from = function.from;
        let q0 = w * mode.low[0] + rho * function.constant + function.slope;
        let q1 = w * mode.low[1] + rho * function.slope;
        let tail = w.abs() * mode.tail;
        let slope_rest = w.abs() * mode.slope_tail;
        let mut pieces = Times::default();
        pieces.push(from);
        // `Q` lies above `q0 + q1·τ − tail·(τ/L)²` (below its mirror), which is concave, so its
        // least value on the chunk is at an end.
        let q_end = q0 + q1 * length_s;
        let zero_free = if q0 > 0.0 {
            q_end - tail > 0.0
        } else if q0 < 0.0 {
            q_end + tail < 0.0
        } else {
            q1 == 0.0 && tail == 0.0
        };
        let monotone = q1.abs() > slope_rest || (q1 == 0.0 && slope_rest == 0.0);
        let q_poly = || self.q_poly(w, mode, [q0, q1]);
        let len = mode.len;
        if !zero_free {
            if !monotone {
                let q = q_poly();
                for &t in zeros(&q[..len], length_s).as_slice() {
                    if t > from && t < length_s {
                        pieces.push(t);
                    }
                }
            } else {
                // A monotone `Q` changes sign after `from` only if `Q(from)` and `Q(L)` differ
                // in sign; `H` then rises and falls where `Q(from) > 0`, a maximum, else falls
                // and rises.
                let mut q = None;
                let q_from = if from > 0.0 {
                    horner(&q.insert(q_poly())[..len], from)
                } else {
                    q0
                };
                let maximum = q_from > 0.0;
                let (g_lo, g_hi) = (function.start, function.end);
                // From zero, the extremum matters only if `g` ends on its other side.
                let needed = if g_lo == 0.0 {
                    if maximum {
                        g_hi <= 0.0
                    } else {
                        g_hi >= 0.0
                    }
                } else {
                    (g_lo > 0.0) == (g_hi > 0.0) && (g_lo > 0.0) != maximum
                };
                if needed {
                    let q = &q.get_or_insert_with(q_poly)[..len];
                    let q_hi = horner(q, length_s);
                    if maximum != (q_hi > 0.0) {
                        let t = refine(|t| jet(q, t), (from, q_from), (length_s, q_hi), EXACT);
                        pieces.push(t);
                    }
                }
            }
        }
        pieces.push(length_s);
        pieces
    }

    /// `g` and `g′` at `τ > 0`.
    fn jet(&self, function: &Function, t: f64) -> (f64, f64) {
        let (value, derivative) = self.derivative_pair(function.order, t);
        let slow = function.weight * value + function.constant + function.slope * t;
        let slope = function.weight * derivative + function.slope;
        if function.fast == 0.0 {
            (slow, slope)
        } else {
            let fast = function.fast * (-self.lag_per_s * t).exp();
            (slow + fast, slope - self.lag_per_s * fast)
        }
    }

    fn value(&self, function: &Function, t: f64) -> f64 {
        if t == function.from {
            function.start
        } else if t == self.length_s {
            function.end
        } else {
            self.jet(function, t).0
        }
    }

    /// The first time at which `g` reaches zero from above, over pieces on each of which it has
    /// at most one zero. A function that starts at zero (a regime entered on its own boundary, as
    /// a part that has just met the plate) ends its regime at once only if it is positive at no
    /// end of a piece of the chunk: a dip of rounding size is no event.
    fn first_zero(&self, function: &Function, pieces: &Times) -> Option<f64> {
        let g = |t: f64| self.value(function, t);
        let points = pieces.as_slice();
        let g_start = g(points[0]);
        if g_start < 0.0 {
            return Some(points[0]);
        }
        let mut rest = points[1..].iter();
        let (mut left, mut g_left) = (points[0], g_start);
        if g_start == 0.0 {
            match rest
                .by_ref()
                .map(|&t| (t, g(t)))
                .find(|&(_, g_t)| g_t > 0.0)
            {
                Some(positive) => (left, g_left) = positive,
                None => return Some(points[0]),
            }
        }
        for &right in rest {
            let g_right = g(right);
            if g_right <= 0.0 {
                return Some(self.zero(function, (left, g_left), (right, g_right), EXACT));
            }
            left = right;
            g_left = g_right;
        }
        None
    }

    /// The zero of `g` between two ends of opposite sign ([`refine`]).
    fn zero(&self, function: &Function, lo: (f64, f64), hi: (f64, f64), relative: f64) -> f64 {
        refine(|t| self.jet(function, t), lo, hi, relative)
    }

    /// Every sign change of `g` over the pieces.
    fn sign_changes(&self, function: &Function, pieces: &Times) -> Times {
        let g = |t: f64| self.value(function, t);
        let points = pieces.as_slice();
        let mut out = Times::default();
        let mut left = points[0];
        let mut g_left = g(left);
        for &right in &points[1..] {
            let g_right = g(right);
            if g_right == 0.0 {
                out.push(right);
            } else if g_left != 0.0 && (g_left > 0.0) != (g_right > 0.0) {
                out.push(self.zero(function, (left, g_left), (right, g_right), TURN));
            }
            left = right;
            g_left = g_right;
        }
        out
    }
}

/// Relative margin on [`Chunk::reach_m`] for the rounding of the values it is built from.
const REACH_MARGIN: f64 = 1e-12;

/// The highest `X` over `[0, L]` from its `(X, X′)` at both ends and bounds `low ≤ X″ ≤ high`:
/// at an end where `X` is convex, else the lower of the two parabolas' highest points.
fn farthest(start: (f64, f64), end: (f64, f64), high: f64, low: f64, length_s: f64) -> f64 {
    if low >= 0.0 {
        return larger(start.0, end.0);
    }
    let (from_start, from_end) = (
        parabola_top(start, high, length_s),
        parabola_top((end.0, -end.1), high, length_s),
    );
    if from_start < from_end {
        from_start
    } else {
        from_end
    }
}

/// The highest point over `s ∈ [0, L]` of `x + v·s + a·s²/2`.
fn parabola_top((x, v): (f64, f64), a: f64, length_s: f64) -> f64 {
    if a < 0.0 && v > 0.0 && v < -a * length_s {
        x - 0.5 * v * v / a
    } else {
        larger(x, x + length_s * (v + 0.5 * a * length_s))
    }
}

/// The larger of two numbers that are not NaN.
fn larger(a: f64, b: f64) -> f64 {
    if a < b {
        b
    } else {
        a
    }
}

/// `Σ_n w_n·p_n·tⁿ` over the shorter of `p` and `w`, as [`horner`] sums.
fn weighted(p: &[f64], w: &[f64], t: f64) -> f64 {
    let len = p.len().min(w.len());
    let (p, w) = (&p[..len], &w[..len]);
    let t2 = t * t;
    let (mut even, mut odd) = (0.0, 0.0);
    let pairs = p.chunks_exact(2).zip(w.chunks_exact(2));
    if len % 2 == 1 {
        even = p[len - 1] * w[len - 1];
    }
    for (pair, weight) in pairs.rev() {
        odd = odd * t2 + pair[1] * weight[1];
        even = even * t2 + pair[0] * weight[0];
    }
    even + t * odd
}

/// `p(t)` by Horner's scheme in `t²` on the even and the odd powers apart: two chains of half
/// the length, which the processor runs side by side.
fn horner(p: &[f64], t: f64) -> f64 {
    let t2 = t * t;
    let (mut even, mut odd) = (0.0, 0.0);
    let pairs = p.chunks_exact(2);
    if let [last] = pairs.remainder() {
        even = *last;
    }
    for pair in pairs.rev() {
        odd = odd * t2 + pair[1];
        even = even * t2 + pair[0];
    }
    even + t * odd
}

/// `p(t)` and `q(t)` for two polynomials of one length, each as [`horner`] sums it.
fn horner_pair(p: &[f64], q: &[f64], t: f64) -> (f64, f64) {
    let t2 = t * t;
    let (mut p_even, mut p_odd, mut q_even, mut q_odd) = (0.0, 0.0, 0.0, 0.0);
    let pairs = p.chunks_exact(2).zip(q.chunks_exact(2));
    if let ([p_last], [q_last]) = (p.chunks_exact(2).remainder(), q.chunks_exact(2).remainder()) {
        p_even = *p_last;
        q_even = *q_last;
    }
    for (p_pair, q_pair) in pairs.rev() {
        p_odd = p_odd * t2 + p_pair[1];
        p_even = p_even * t2 + p_pair[0];
        q_odd = q_odd * t2 + q_pair[1];
        q_even = q_even * t2 + q_pair[0];
    }
    (p_even + t * p_odd, q_even + t * q_odd)
}

/// `p(t)` and `p′(t)`.
fn jet(p: &[f64], t: f64) -> (f64, f64) {
    (horner(p, t), weighted(&p[1..], &FALLING[1][1..], t))
}

/// Steps of [`refine`] end below this fraction of the time: a few units in the last place.
const EXACT: f64 = 4.0 * f64::EPSILON;

/// Steps of [`refine`] for a turning point end below this fraction of the time: the plate's
/// position is stationary there, so its error is of the order of the square of the time's.
const TURN: f64 = 1e-9;

/// The zero of `f` in `[lo, hi]`, given `f(lo) > 0 ≥ f(hi)` (or the reverse) and a single sign
/// change between: Newton's steps from the secant's point, kept inside the shrinking bracket
/// (bisecting where a step would leave it), until a step is below `relative` of the time, or
/// until two Newton steps in a row shrink so fast that the next, `|s_k|³/|s_{k−1}|²` for
/// quadratic convergence, would be (then the last step is taken unevaluated). `f_df` gives `f`
/// and `f′`.
fn refine(
    f_df: impl Fn(f64) -> (f64, f64),
    (mut lo, f_lo): (f64, f64),
    (mut hi, f_hi): (f64, f64),
    relative: f64,
) -> f64 {
    let lo_positive = f_lo > 0.0;
    let mut t = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
    if !(t > lo && t < hi) {
        t = 0.5 * (lo + hi);
    }
    // The last step if it was Newton's, else 0.
    let mut last_step = 0.0;
    for _ in 0..200 {
        let (f, df) = f_df(t);
        if f == 0.0 {
            return t;
        }
        if (f > 0.0) == lo_positive {
            lo = t;
        } else {
            hi = t;
        }
        let step = f / df;
        let tolerance = relative * t.abs();
        if step.abs() <= tolerance {
            return t;
        }
        let newton = t - step;
        let inside = newton > lo && newton < hi;
        if inside && step.abs().powi(3) <= tolerance * last_step * last_step {
            return newton;
        }
        (t, last_step) = if inside {
            (newton, step.abs())
        } else {
            (0.5 * (lo + hi), 0.0)
        };
        if t <= lo || t >= hi {
            break;
        }
    }
    hi
}

/// The Taylor coefficients of `p′`.
fn derivative(p: &[f64]) -> Poly {
    let mut out = [0.0; TERMS];
    for n in 0..p.len() - 1 {
        out[n] = (n + 1) as f64 * p[n + 1];
    }
    out
}

/// The zeros of `Q` in `[0, length_s]` at which it changes sign, sorted: `Q″` has at most one
/// there (see the module's notes), bracketed by its signs at the ends; `Q′` is monotone on each
/// side of it and `Q` on each side of `Q′`'s zeros. The derivatives' zeros only split the level
/// below into monotone pieces, to 10⁻⁹ of the time: a split off by that could hide only a double
/// zero of rounding size.
fn zeros(q: &[f64], length_s: f64) -> Times {
    let len = q.len();
    let slope = derivative(q);
    let curvature = derivative(&slope[..len]);
    let mut found = Times::default();
    for (p, tolerance) in [(&curvature[..len], TURN), (&slope[..len], TURN), (q, EXACT)] {
        let mut next = Times::default();
        let mut left = 0.0;
        let mut f_left = p[0];
        for right in found.as_slice().iter().copied().chain([length_s]) {
            let f_right = horner(p, right);
            if (f_left > 0.0) != (f_right > 0.0) {
                next.push(refine(
                    |t| jet(p, t),
                    (left, f_left),
                    (right, f_right),
                    tolerance,
                ));
            }
            left = right;
            f_left = f_right;
        }
        found = next;
    }
    found
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::super::linear::{State, F, P, Q, U, V, X};
    use super::super::motion::{Event, Model, Part, Slide};
    use super::super::params::PlateParams;
    use super::super::regime::Regimes;
    use super::{Course, FreeSlide};
    use crate::contact::Contact;

    /// A free slide with a current loop of 0.1 Hz to 100 kHz (or none), a spring up to
    /// 10⁷ N/m (up to 7 kHz on the lightest plate) and damping up to 5000 N·s/m.
    fn free_plate() -> impl Strategy<Value = PlateParams> {
        (
            0.2..5.0_f64,
            prop_oneof![Just(None), (0.1..1e5_f64).prop_map(Some)],
            prop_oneof![Just(0.0), 0.0..1e5_f64, 0.0..1e7_f64],
            prop_oneof![Just(0.0), 0.0..200.0_f64, 0.0..5000.0_f64],
            prop_oneof![Just(None), (1e-3..1e-2_f64).prop_map(Some)],
        )
            .prop_map(
                |(mass_kg, f_c, spring_npm, damping, end_stop_m)| PlateParams {
                    mass_kg,
                    current_bandwidth_hz: f_c,
                    spring_npm,
                    spring_damping_nspm: damping,
                    end_stop_m,
                    ..PlateParams::default()
                },
            )
    }

    /// A solver's outcome over a stretch: its first event with its time, the state then, and
    /// the plate's peak distance from the centre so far (at its ends and turning points).
    type Outcome = (Option<(Event, f64)>, State, f64);

    /// Both solvers from the same state: the general one through its regime's matrix.
    fn both(
        model: &Model,
        part: Part,
        target_n: f64,
        z: &State,
        duration_s: f64,
    ) -> (Outcome, Outcome) {
        let free = FreeSlide::new(model).expect("a free slide");
        let mut free_peak = z[X].abs();
        let (free_event, free_z) = free.next_event(part, target_n, z, duration_s, &mut free_peak);
        let mut regimes = Regimes::default();
        let regime = regimes.get(model, Slide::Free, part, target_n);
        let mut peak = z[X].abs();
        let (event, end_z) = model.next_event(regime, z, duration_s, |x| peak = peak.max(x.abs()));
        (
            (free_event, free_z, free_peak.max(free_z[X].abs())),
            (event, end_z, peak.max(end_z[X].abs())),
        )
    }

    /// A plate without spring or damping up to a stiff, heavily damped one, from 1 g to 1 t.
    fn extreme_plate() -> impl Strategy<Value = PlateParams> {
        (
            free_plate(),
            prop_oneof![0.001..0.1_f64, 0.2..5.0_f64, 10.0..1000.0_f64],
        )
            .prop_map(|(plate, mass_kg)| PlateParams { mass_kg, ..plate })
    }

    /// The part's contact and state, the command and the stretch's length of one check.
    #[derive(Debug)]
    struct Case {
        mu: f64,
        extra_static: f64,
        start: [f64; 6],
        stuck: bool,
        command_mps2: f64,
        duration_s: f64,
    }

    /// A part's contact and state, with commands and stretches from the strategies given.
    fn case(
        command_mps2: impl Strategy<Value = f64>,
        duration_s: impl Strategy<Value = f64>,
    ) -> impl Strategy<Value = Case> {
        (
            0.05..1.0_f64,
            prop_oneof![Just(0.0), 0.0..0.5_f64],
            prop::array::uniform6(-1.0..1.0_f64),
            any::<bool>(),
            command_mps2,
            duration_s,
        )
            .prop_map(
                |(mu, extra_static, start, stuck, command_mps2, duration_s)| Case {
                    mu,
                    extra_static,
                    start,
                    stuck,
                    command_mps2,
                    duration_s,
                },
            )
    }

    /// The case's model, drive target and settled state with the part's contact.
    fn setup(params: PlateParams, case: &Case) -> (Model, f64, State, Part) {
        let contact = Contact::new(case.mu, case.mu + case.extra_static, 9.81, 1e-4, 0.0).unwrap();
        let model = Model::new(params, contact);
        let target_n = params.target_force_n(case.command_mps2);
        let x_lim = params.end_stop_m.unwrap_or(1e-2);
        let start = case.start;
        let mut z: State = [
            0.9 * x_lim * start[0],
            0.3 * start[1],
            params.mass_kg * 200.0 * start[2],
            0.3 * start[3],
            start[4],
            1e-3 * start[5],
            1.0,
        ];
        if params.current_bandwidth_hz.is_none() {
            z[F] = target_n;
        }
        let mut slide = Slide::Free;
        let mut part = if case.stuck {
            Part::Stuck
        } else {
            Part::Sliding((z[U] - z[V]).signum())
        };
        model.settle(&mut z, &mut slide, &mut part);
        (model, target_n, z, part)
    }

    /// The free slide's outcome and the general solver's from one state agree: the same event,
    /// at the same time to 10⁻⁹ of the stretch, and the same state and peak excursion to 10⁻⁹ of
    /// their scale (or of the value, where the plate has gone further).
    fn close(
        params: &PlateParams,
        duration_s: f64,
        free: &Outcome,
        general: &Outcome,
    ) -> Result<(), TestCaseError> {
        let x_lim = params.end_stop_m.unwrap_or(1e-2);
        let kind = |e: Option<(Event, f64)>| e.map(|(event, _)| event);
        prop_assert_eq!(kind(free.0), kind(general.0));
        if let (Some((_, t_free)), Some((_, t))) = (free.0, general.0) {
            prop_assert!(
                (t_free - t).abs() <= 1e-9 * duration_s,
                "{} vs {}",
                t_free,
                t
            );
        }
        let scale = [x_lim, 1.0, params.mass_kg * 200.0, 1.0, 1.0, 1e-3];
        for (i, s) in [X, V, F, U, P, Q].into_iter().zip(scale) {
            prop_assert!(
                (free.1[i] - general.1[i]).abs() <= 1e-9 * s.max(general.1[i].abs()),
                "state {}: {:e} vs {:e}",
                i,
                free.1[i],
                general.1[i]
            );
        }
        // A stiff, damped spring rings down through turning points of rounding size near its
        // rest, which the general solver may pass over, so turning points are compared by the
        // peak they give.
        let (free_peak, general_peak) = (free.2, general.2);
        prop_assert!(
            (free_peak - general_peak).abs() <= 1e-9 * x_lim.max(general_peak),
            "peak {:e} vs {:e}",
            free_peak,
            general_peak
        );
        Ok(())
    }

    /// Both solvers from the case's state agree on the first event ([`close`]).
    fn agree(params: PlateParams, case: Case) -> Result<(), TestCaseError> {
        let (model, target_n, z, part) = setup(params, &case);
        let (free, general) = both(&model, part, target_n, &z, case.duration_s);
        close(&params, case.duration_s, &free, &general)
    }

    /// Event by event through the case's stretch, as the stepper runs it, split into segments
    /// at the fractions `splits` of it (the target holding through all): after each of the
    /// part's events the course goes on in its chunk, and across each segment's end; every step
    /// agrees with the general solver from the same state over the rest of its segment
    /// ([`close`]). Returns how many events the course found.
    fn agree_through(
        params: PlateParams,
        case: Case,
        splits: &[f64],
    ) -> Result<usize, TestCaseError> {
        let (model, target_n, mut z, mut part) = setup(params, &case);
        let free = FreeSlide::new(&model).expect("a free slide");
        let mut course = Course::default();
        let mut regimes = Regimes::default();
        let mut slide = Slide::Free;
        // The peaks run on through the stretch, as the stepper's: the course need not seek the
        // turning points of a chunk that stays below its peak.
        let (mut free_peak, mut general_peak) = (z[X].abs(), z[X].abs());
        let ends_s: Vec<f64> = splits
            .iter()
            .map(|fraction| fraction * case.duration_s)
            .chain([case.duration_s])
            .collect();
        let mut events = 0;
        let mut start_s = 0.0;
        for &end_s in &ends_s {
            let duration_s = end_s - start_s;
            course.begin(target_n, duration_s, case.duration_s - start_s);
            start_s = end_s;
            let mut offset_s = 0.0;
            loop {
                model.settle(&mut z, &mut slide, &mut part);
                let rest_s = (duration_s - offset_s).max(0.0);
                let (event, end_z) = course.next_event(&free, part, &z, offset_s, &mut free_peak);
                free_peak = free_peak.max(end_z[X].abs());
                let regime = regimes.get(&model, slide, part, target_n);
                let (general_event, general_z) = model.next_event(regime, &z, rest_s, |x| {
                    general_peak = general_peak.max(x.abs());
                });
                general_peak = general_peak.max(general_z[X].abs());
                close(
                    &params,
                    duration_s,
                    &(event, end_z, free_peak),
                    &(general_event, general_z, general_peak),
                )?;
                z = end_z;
                if part == Part::Stuck {
                    z[U] = z[V];
                }
                match event {
                    None => break,
                    Some((Event::EndStop, _)) => return Ok(events),
                    Some((event, t)) => {
                        events += 1;
                        if events == 100 {
                            return Ok(events);
                        }
                        offset_s += t;
                        model.apply(event, &mut z, &mut slide, &mut part);
                    }
                }
            }
        }
        Ok(events)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// From any state of a feeder's plate, the scalar solution agrees with the general
        /// solver.
        #[test]
        fn the_free_slide_agrees_with_the_general_solver(
            params in free_plate(),
            case in case(-200.0..200.0_f64, 1e-4..2e-2_f64),
        ) {
            agree(params, case)?;
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1000))]

        /// Through a whole stretch of a feeder's plate, event by event, the course that goes
        /// on in its chunk after the part's events, and across a segment's end where the next
        /// holds the target, agrees with the general solver.
        #[test]
        fn a_course_through_a_stretch_agrees_with_the_general_solver(
            params in free_plate(),
            case in case(-200.0..200.0_f64, 1e-3..2e-2_f64),
            split in prop_oneof![Just(None), (0.01..0.99_f64).prop_map(Some)],
        ) {
            agree_through(params, case, split.as_slice())?;
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// Far outside a feeder's range (masses of 1 g to 1 t, commands of 10⁴ m/s², stretches
        /// of a nanosecond to a second) the two solvers still agree.
        #[test]
        fn the_free_slide_agrees_far_outside_a_feeder_s_range(
            params in extreme_plate(),
            case in case(
                prop_oneof![-200.0..200.0_f64, -1e4..1e4_f64],
                prop_oneof![1e-9..1e-4_f64, 1e-4..2e-2_f64, 2e-2..1.0_f64],
            ),
        ) {
            agree(params, case)?;
        }
    }

    /// A part ahead of a stiffly sprung plate meets it where the gap dips below zero inside a
    /// chunk and opens again before the chunk ends: the bounds over the chunk must see the dip.
    #[test]
    fn a_meeting_inside_a_chunk_whose_ends_are_apart_is_found() {
        let params = PlateParams {
            mass_kg: 1.5445275830089054,
            current_bandwidth_hz: Some(4618.427662729602),
            spring_npm: 71404.21044409128,
            spring_damping_nspm: 170.2373076535165,
            end_stop_m: Some(0.003149768373894266),
            ..PlateParams::default()
        };
        let contact = Contact::kinetic(0.6278634258754741, 1e-4).unwrap();
        let model = Model::new(params, contact);
        let target_n = params.target_force_n(81.8732739340645);
        let z: State = [2.852e-4, 0.0, 0.0, 0.2657, 0.0, 0.0, 1.0];
        let (free, general) = both(&model, Part::Sliding(1.0), target_n, &z, 0.0135);
        let (Some((Event::PartMeetsPlate, t_free)), Some((Event::PartMeetsPlate, t))) =
            (free.0, general.0)
        else {
            panic!("the part meets the plate: {free:?} {general:?}");
        };
        assert!((t_free - t).abs() < 1e-15, "{t_free} vs {t}");
    }

    /// The benchmark's plate: 1.5 kg, a 1 kHz current loop, an 18 Hz spring (2·10⁴ N/m) with
    /// 20 N·s/m of damping.
    fn lag_spring_plate() -> PlateParams {
        PlateParams {
            mass_kg: 1.5,
            current_bandwidth_hz: Some(1000.0),
            spring_npm: 2e4,
            spring_damping_nspm: 20.0,
            ..PlateParams::default()
        }
    }

    /// A part that has just met the plate starts its regime on the boundary (`u = v`) and must
    /// not end it at once: the first event is the next one, as the general solver has it.
    #[test]
    fn a_regime_entered_on_its_boundary_does_not_end_at_once() {
        let params = lag_spring_plate();
        let model = Model::new(params, Contact::kinetic(0.3, 1e-4).unwrap());
        // Accelerating at 67 m/s², the drive turning to −146 m/s²: the part slides behind, then
        // meets the plate when it has slowed.
        let target_n = params.target_force_n(-146.0);
        let mut z: State = [1e-4, 0.05, 100.0, 0.0, 0.0, 0.0, 1.0];
        z[U] = z[V];
        let mut slide = Slide::Free;
        let mut part = Part::Stuck;
        model.settle(&mut z, &mut slide, &mut part);
        assert!(matches!(part, Part::Sliding(_)));
        let (free, general) = both(&model, part, target_n, &z, 5e-3);
        assert_eq!(free.0.map(|(e, _)| e), general.0.map(|(e, _)| e));
        let (Some((_, t_free)), Some((_, t))) = (free.0, general.0) else {
            panic!("the part meets the plate again: {free:?} {general:?}");
        };
        assert!(t > 1e-4 && (t_free - t).abs() < 1e-15, "{t_free} vs {t}");
    }

    /// 8 ms of a 1.5 kg plate on an 18 Hz spring (whose chunks last up to 8.7 ms) with three of
    /// the part's events.
    fn three_events() -> (PlateParams, Case) {
        let params = lag_spring_plate();
        let case = Case {
            mu: 0.1,
            extra_static: 0.0,
            start: [0.0, 0.5, 0.0, -0.5, 0.0, 0.0],
            stuck: true,
            command_mps2: 146.0,
            duration_s: 8e-3,
        };
        (params, case)
    }

    /// Three of the part's events within one chunk: the course goes on in its chunk after each,
    /// and agrees with the general solver.
    #[test]
    fn a_course_goes_on_in_its_chunk_after_the_part_s_events() {
        let (params, case) = three_events();
        let events = agree_through(params, case, &[]).expect("the solvers agree");
        assert_eq!(events, 3);
    }

    /// The same stretch cut into three segments of one target: the course goes on across their
    /// ends, through the same three events.
    #[test]
    fn a_course_goes_on_across_segments_that_hold_the_target() {
        let (params, case) = three_events();
        let events = agree_through(params, case, &[0.3, 0.6]).expect("the solvers agree");
        assert_eq!(events, 3);
    }

    /// A course keeps its chunk-end maps for one free slide: moved to another, it finds what a
    /// new course finds there.
    #[test]
    fn a_course_drops_its_end_maps_on_another_free_slide() {
        let (params, _) = three_events();
        let stiffer = PlateParams {
            spring_npm: 8e4,
            ..params
        };
        // A part held fast: each segment runs to its end, from the map from the second on.
        let case = Case {
            mu: 10.0,
            extra_static: 0.0,
            start: [0.1, 0.5, 0.0, 0.0, 0.0, 0.0],
            stuck: true,
            command_mps2: 10.0,
            duration_s: 1e-3,
        };
        let run = |course: &mut Course, params: PlateParams| {
            let (model, target_n, z, part) = setup(params, &case);
            let free = FreeSlide::new(&model).expect("a free slide");
            let mut peak_m = 0.0;
            let mut outcomes = Vec::new();
            for _ in 0..3 {
                course.begin(target_n, 1e-3, 1e-3);
                outcomes.push(course.next_event(&free, part, &z, 0.0, &mut peak_m));
            }
            assert!(outcomes.iter().all(|(event, _)| event.is_none()));
            format!("{outcomes:?} {peak_m}")
        };
        let mut moved = Course::default();
        run(&mut moved, params);
        assert_eq!(
            run(&mut moved, stiffer),
            run(&mut Course::default(), stiffer)
        );
    }

    /// `Q = (τ − 0.1)·(τ − 0.5)·(τ − 0.9)` on `[0, 1]`: `Q″ = 6τ − 3` has its one zero at 0.5, `Q′`
    /// two (`0.5 ± √0.0533…`) where `Q` is positive at both ends, and `Q` all three of its zeros.
    #[test]
    fn all_three_zeros_of_q_are_found_through_its_derivatives() {
        let q = [-0.045, 0.59, -1.5, 1.0];
        let found = super::zeros(&q, 1.0);
        let found = found.as_slice();
        assert_eq!(found.len(), 3, "{found:?}");
        for (t, expected) in found.iter().zip([0.1, 0.5, 0.9]) {
            assert!((t - expected).abs() < 1e-14, "{found:?}");
        }
    }

    /// Slide friction and a current loop at one of the slide's own rates are left to the general
    /// solver.
    #[test]
    fn only_a_free_slide_with_a_separable_current_loop_is_solved_in_closed_form() {
        let contact = Contact::kinetic(0.3, 1e-4).unwrap();
        let friction = PlateParams {
            coulomb_friction_n: 1.0,
            ..PlateParams::default()
        };
        assert!(FreeSlide::new(&Model::new(friction, contact)).is_none());
        // M·ρ² − c·ρ + k = 0 at ρ = 2π·100 Hz with M = 1 kg and c = 2·M·ρ: k = M·ρ².
        let rho = 2.0 * std::f64::consts::PI * 100.0;
        let resonant = PlateParams {
            current_bandwidth_hz: Some(100.0),
            spring_npm: rho * rho,
            spring_damping_nspm: 2.0 * rho,
            ..PlateParams::default()
        };
        assert!(FreeSlide::new(&Model::new(resonant, contact)).is_none());
        assert!(FreeSlide::new(&Model::new(PlateParams::default(), contact)).is_some());
    }
}
