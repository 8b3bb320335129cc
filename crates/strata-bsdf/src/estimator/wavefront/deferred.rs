//! Path continuations from medium collisions, deferred until a chunk's worth
//! is pending.
//!
//! After a collision, an eval walk whose new direction heads for a rough exit
//! adds the exit's BSDF toward the viewer, MIS-weighted
//! ([`events::continue_to_exit`]): an `eval` and a `pdf` of the exit
//! interface, the costliest kernels of a layer event. In a chunk only the
//! lanes heading for the exit need it (about half of them, in a thick
//! medium), but run in place it would cost the whole chunk. So those lanes
//! leave a row here instead, and the kernel runs on full chunks of rows (the
//! last few of a task when it ends).
//!
//! A walk's continuations are summed in the order they were made, apart from
//! its other contributions, and added to them when the task ends; the scalar
//! engine sums them the same way (`Connect::from_collisions`), so walk values
//! stay bit for bit the scalar engine's.

use super::engine::{Queries, Wavefront};
use super::walks::{lane_ids, lane_rows, Chunk};
use crate::estimator::events;
use crate::lane::{load16, Rgb, Wide, LANE_IDS, MAX_LANES, V3};

/// One pending continuation: the viewer direction `wo` (3), the direction
/// before the collision (3) and after it (3), the depth to the exit's side
/// of the layer, the throughput (3), the walk (its index in the task) and
/// its query (both as float bits); one unused.
type Row = [f32; 16];
const WALK: usize = 13;
const QUERY: usize = 14;

/// The pending continuations of a task, per rough exit, and each walk's sum.
#[derive(Default)]
pub(super) struct Deferred {
    /// Rows per exit, in the order of `Wavefront::exits`.
    pending: Vec<Vec<Row>>,
    /// The lanes of the engine that runs the task: a chunk's worth of rows.
    /// (The one-lane engine that finishes a task's last walks only adds
    /// rows; what is left runs when the task ends.)
    lanes: usize,
    /// Per walk of the task: the sum of its continuations so far.
    sums: Vec<[f32; 3]>,
}

impl Deferred {
    /// Empties it for a task of `walks` walks on an engine of `lanes` lanes
    /// with `exits` rough exits, keeping its memory (a thread reuses one
    /// task after task).
    pub(super) fn reset(&mut self, exits: usize, walks: usize, lanes: usize) {
        self.pending.resize_with(exits, Vec::new);
        self.pending.iter_mut().for_each(Vec::clear);
        self.lanes = lanes;
        self.sums.clear();
        self.sums.resize(walks, [0.0; 3]);
    }

    /// Defers the continuation toward exit `x` of lanes `lanes` (a bitmask),
    /// whose walks (their indices in the task) are `walk`. `fields`: `wo`, the
    /// old and the new direction, the depth to the exit's side, the throughput.
    #[inline(always)]
    pub(super) fn push<W: Wide>(
        &mut self,
        x: usize,
        lanes: u32,
        (walk, query): (W::Bits, W::Bits),
        (wo, d, dn, dz, beta): (V3<W>, V3<W>, V3<W>, W, Rgb<W>),
    ) {
        let z = W::zero();
        let lo = [wo.x, wo.y, wo.z, d.x, d.y, d.z, dn.x, dn.y];
        let hi = [
            dn.z,
            dz,
            beta.r,
            beta.g,
            beta.b,
            W::from_bit_lanes(walk),
            W::from_bit_lanes(query),
            z,
        ];
        // Whole rows, stored by two transposes (as `lane_rows`, sixteen wide).
        let mut rows = [[0.0f32; 16]; MAX_LANES];
        let ids = &LANE_IDS[..W::LANES];
        W::store8(lo, &mut rows[..W::LANES], ids, 0);
        W::store8(hi, &mut rows[..W::LANES], ids, 8);
        let pending = &mut self.pending[x];
        for j in Chunk::<W>::set_bits(lanes) {
            pending.push(rows[j]);
        }
    }

    /// Whether exit `x` has a full chunk of rows pending for an engine of
    /// `lanes` lanes to run (only the task's own engine runs them).
    #[inline(always)]
    pub(super) fn full(&self, x: usize, lanes: usize) -> bool {
        lanes == self.lanes && self.pending[x].len() >= lanes
    }

    /// Adds each walk's sum to its value (`values`, in walk order): the task
    /// is over, and every row has run.
    pub(super) fn add_sums<'a>(&self, values: impl Iterator<Item = &'a mut [f32; 3]>) {
        debug_assert!(self.pending.iter().all(Vec::is_empty));
        for (v, s) in values.zip(&self.sums) {
            add3(v, s);
        }
    }
}

/// `v += s`, channel by channel.
#[inline(always)]
fn add3(v: &mut [f32; 3], s: &[f32]) {
    *v = [v[0] + s[0], v[1] + s[1], v[2] + s[2]];
}

impl<W: Wide> Wavefront<W> {
    /// Runs the pending continuations toward exit `x`, a chunk of rows at a
    /// time, oldest first: the full chunks only, or (`all`) every row.
    pub(super) fn run_deferred(&self, q: &Queries, def: &mut Deferred, x: usize, all: bool) {
        let (e, l, _) = self.exits[x];
        let rows = std::mem::take(&mut def.pending[x]);
        let whole = rows.len() / W::LANES * W::LANES;
        let end = if all { rows.len() } else { whole };
        for first in (0..end).step_by(W::LANES) {
            let n = W::LANES.min(end - first);
            // A partial chunk repeats its last row in the idle lanes.
            let idx = lane_ids(&LANE_IDS[..n], |j| first as u32 + j);
            let f = load16::<W, 16>(&rows, &idx[..W::LANES], 0);
            let (wo, d) = (V3::new(f[0], f[1], f[2]), V3::new(f[3], f[4], f[5]));
            let (dn, dz) = (V3::new(f[6], f[7], f[8]), f[9]);
            let beta = Rgb::new(f[10], f[11], f[12]);
            let sets = q.lane_sets(W::LANES, |j| rows[idx[j] as usize][QUERY].to_bits());
            let (exit, med) = (self.iface_in(&sets, e), self.medium_in(&sets, l));
            // As in the scalar engine's collision, in the same order.
            let add = events::collision_continuation(&exit, &med, wo, d, dn, dz, beta);
            let z = W::zero();
            let out = lane_rows([add.r, add.g, add.b, z, z, z, z, z]);
            for (j, r) in rows[first..first + n].iter().enumerate() {
                add3(&mut def.sums[r[WALK].to_bits() as usize], &out[j][..3]);
            }
        }
        let mut rows = rows;
        rows.drain(..end);
        def.pending[x] = rows;
    }
}
