//! Walk state in structure-of-arrays columns, and its lane view.
//!
//! A wave holds a fixed number of walk slots. Hot columns (depth, direction,
//! throughput, channel ratios, counters, flags, random state) are gathered
//! into lanes for a stage and scattered back; cold columns (which query, which
//! output slot, the adjoint chain) are read by index. A slot's `key` says
//! which queue it is in: interface `i` (`key = i`), scattering layer `l`
//! (`key = n + l`), or [`FREE`].

use crate::estimator::events::Connection;
use crate::lane::{LaneMask, Rgb, Wide, V3};
use crate::rng::LaneRng;

/// The key of an empty slot.
pub const FREE: u16 = u16::MAX;

/// One segment of a walk's adjoint chain, with the transmittance of a full
/// crossing of its layer (what a surface vertex connects through).
#[derive(Clone, Copy, Debug)]
pub struct Link {
    /// The connection.
    pub conn: Connection<f32>,
    /// Transmittance of the whole layer along `conn.u`.
    pub t_full: Rgb<f32>,
    /// The layer the segment crosses.
    pub layer: u16,
    /// The interface it starts from.
    pub start: u16,
}

/// The walk columns of one wave.
#[derive(Debug, Default)]
pub struct Walks {
    /// Queue key per slot.
    pub key: Vec<u16>,
    /// The walk's index in its task (its output slot).
    pub walk: Vec<u32>,
    /// The walk's query (index into the batch's prepared queries).
    pub query: Vec<u32>,
    /// Depth in the current layer.
    pub z: Vec<f32>,
    /// Travel direction.
    pub d: [Vec<f32>; 3],
    /// Throughput.
    pub beta: [Vec<f32>; 3],
    /// Spectral-MIS channel ratios.
    pub ratios: [Vec<f32>; 3],
    /// Hero channel (0, 1, 2).
    pub hero: Vec<f32>,
    /// Events so far.
    pub events: Vec<f32>,
    /// Medium collisions so far.
    pub order: Vec<f32>,
    /// 1 at the entrance vertex, else 0.
    pub first: Vec<f32>,
    /// 1 while every event was a delta, else 0.
    pub specular: Vec<f32>,
    /// Accumulated contribution (eval).
    pub acc: [Vec<f32>; 3],
    /// Xoshiro128++ state of the walk stream.
    pub rng: [Vec<u32>; 4],
    /// The adjoint chain (eval).
    pub chain: Vec<Vec<Link>>,
}

impl Walks {
    /// A wave of `slots` empty slots.
    pub fn new(slots: usize) -> Self {
        let f = || vec![0.0f32; slots];
        let f3 = || [f(), f(), f()];
        Walks {
            key: vec![FREE; slots],
            walk: vec![0; slots],
            query: vec![0; slots],
            z: f(),
            d: f3(),
            beta: f3(),
            ratios: f3(),
            hero: f(),
            events: f(),
            order: f(),
            first: f(),
            specular: f(),
            acc: f3(),
            rng: std::array::from_fn(|_| vec![0u32; slots]),
            chain: vec![Vec::new(); slots],
        }
    }

    /// Number of slots.
    pub fn slots(&self) -> usize {
        self.key.len()
    }
}

/// The hot state of up to `W::LANES` walks, in lanes.
#[derive(Clone, Copy)]
pub struct Chunk<W: Wide> {
    /// Lanes holding a walk of this chunk (a partial chunk has fewer).
    pub active: W::Mask,
    /// Depth.
    pub z: W,
    /// Travel direction.
    pub d: V3<W>,
    /// Throughput.
    pub beta: Rgb<W>,
    /// Channel ratios.
    pub ratios: Rgb<W>,
    /// Hero channel.
    pub hero: W,
    /// Events so far.
    pub events: W,
    /// Collisions so far.
    pub order: W,
    /// At the entrance vertex.
    pub first: W::Mask,
    /// Every event so far was a delta.
    pub specular: W::Mask,
    /// Accumulated contribution.
    pub acc: Rgb<W>,
    /// Random state.
    pub rng: LaneRng<W>,
}

fn v3<W: Wide>(c: &[Vec<f32>; 3], idx: &[u32]) -> V3<W> {
    V3::new(
        W::gather(&c[0], idx),
        W::gather(&c[1], idx),
        W::gather(&c[2], idx),
    )
}
fn rgb<W: Wide>(c: &[Vec<f32>; 3], idx: &[u32]) -> Rgb<W> {
    Rgb::new(
        W::gather(&c[0], idx),
        W::gather(&c[1], idx),
        W::gather(&c[2], idx),
    )
}
fn put3<W: Wide>(v: [W; 3], c: &mut [Vec<f32>; 3], idx: &[u32], m: W::Mask) {
    for (x, col) in v.into_iter().zip(c.iter_mut()) {
        x.scatter(col, idx, m);
    }
}
fn flag<W: Wide>(m: W::Mask) -> W {
    W::select(m, W::one(), W::zero())
}

impl<W: Wide> Chunk<W> {
    /// Loads slots `idx` (exactly `W::LANES` entries; lanes beyond `active`
    /// repeat a valid slot and are never written back).
    #[inline]
    pub fn gather(ws: &Walks, idx: &[u32], active: W::Mask) -> Self {
        let half = W::splat(0.5);
        Chunk {
            active,
            z: W::gather(&ws.z, idx),
            d: v3(&ws.d, idx),
            beta: rgb(&ws.beta, idx),
            ratios: rgb(&ws.ratios, idx),
            hero: W::gather(&ws.hero, idx),
            events: W::gather(&ws.events, idx),
            order: W::gather(&ws.order, idx),
            first: W::gather(&ws.first, idx).gt(half),
            specular: W::gather(&ws.specular, idx).gt(half),
            acc: rgb(&ws.acc, idx),
            rng: LaneRng::gather(&ws.rng, idx),
        }
    }

    /// Stores the active lanes back.
    #[inline]
    pub fn scatter(&self, ws: &mut Walks, idx: &[u32]) {
        let m = self.active;
        self.z.scatter(&mut ws.z, idx, m);
        put3([self.d.x, self.d.y, self.d.z], &mut ws.d, idx, m);
        put3(
            [self.beta.r, self.beta.g, self.beta.b],
            &mut ws.beta,
            idx,
            m,
        );
        let r = self.ratios;
        put3([r.r, r.g, r.b], &mut ws.ratios, idx, m);
        self.hero.scatter(&mut ws.hero, idx, m);
        self.events.scatter(&mut ws.events, idx, m);
        self.order.scatter(&mut ws.order, idx, m);
        flag::<W>(self.first).scatter(&mut ws.first, idx, m);
        flag::<W>(self.specular).scatter(&mut ws.specular, idx, m);
        put3([self.acc.r, self.acc.g, self.acc.b], &mut ws.acc, idx, m);
        self.rng.scatter(&mut ws.rng, idx, m);
    }

    /// A per-lane query value from a per-query column.
    #[inline]
    pub fn per_query(col: &[f32], queries: &[u32]) -> W {
        W::gather(col, queries)
    }

    /// Lanes whose mask bit is set in both.
    #[inline]
    pub fn lanes(m: W::Mask) -> impl Iterator<Item = usize> {
        let bits = W::bitmask(m);
        (0..W::LANES).filter(move |j| bits & (1 << j) != 0)
    }

    /// True if `m` has no lane set.
    #[inline]
    pub fn none(m: W::Mask) -> bool {
        !m.any()
    }
}

/// A lane value as f32 (lane `j`).
#[inline]
pub fn lane_f32<W: Wide>(x: W, j: usize) -> f32 {
    x.lane(j) as f32
}
