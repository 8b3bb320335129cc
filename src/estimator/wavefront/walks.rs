//! Walk state, and its lane view.
//!
//! A wave holds a fixed number of walk slots. The hot state of a slot (depth,
//! direction, throughput, channel ratios, counters, flags, random state, the
//! first link of the adjoint chain) is one record of [`REC`] floats, laid out
//! in blocks of eight fields so that a stage loads only the blocks it uses:
//! loading a chunk is a few vector loads and in-register transposes
//! ([`Wide::load_block`]), which makes each block a structure-of-arrays tile
//! of the chunk's walks. Cold columns (queue key, output slot, query, the rest
//! of the chain) are read by index.
//!
//! A slot's `key` says which queue it is in: interface `i` (`key = i`),
//! scattering layer `l` (`key = n + l`), or [`FREE`].

use crate::estimator::events::Connection;
use crate::lane::{LaneMask, Rgb, Wide, V3};
use crate::rng::LaneRng;

/// The key of an empty slot.
pub const FREE: u16 = u16::MAX;

/// Floats per walk record (a multiple of 16, so both lane widths tile it).
pub const REC: usize = 48;

/// Field offsets in a record, by block of eight.
mod f {
    // Block 0: every stage.
    pub const D: usize = 0;
    pub const BETA: usize = 3;
    pub const EVENTS: usize = 6;
    pub const SPECULAR: usize = 7;
    // Block 1: every stage.
    pub const RNG: usize = 8;
    pub const FIRST: usize = 12;
    pub const HERO: usize = 13;
    pub const ORDER: usize = 14;
    pub const Z: usize = 15;
    // Block 2: layer events, and eval.
    pub const RATIOS: usize = 16;
    pub const ACC: usize = 19;
    pub const LINKS: usize = 22;
    // Blocks 3 and 4: eval (the chain's first link).
    pub const L0_U: usize = 24;
    pub const L0_V: usize = 27;
    pub const L0_MIS: usize = 30;
    pub const L0_LAYER: usize = 31;
    pub const L0_T: usize = 32;
    pub const L0_START: usize = 35;
    // The query's outgoing direction and exit (eval), beside the link.
    pub const WO: usize = 36;
    pub const E_OUT: usize = 39;
    pub const END: usize = 40;
}

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

/// A link in lanes.
#[derive(Clone, Copy)]
pub struct LinkLanes<W: Wide> {
    /// The connection.
    pub conn: Connection<W>,
    /// Full-crossing transmittance.
    pub t: Rgb<W>,
    /// Layer.
    pub layer: W,
    /// Start interface.
    pub start: W,
}

/// The walks of one wave.
#[derive(Debug, Default)]
pub struct Walks {
    /// Queue key per slot.
    pub key: Vec<u16>,
    /// The walk's index in its task (its output slot).
    pub walk: Vec<u32>,
    /// The walk's query (index into the batch's prepared queries).
    pub query: Vec<u32>,
    /// Hot state, one record per slot.
    pub rec: Vec<[f32; REC]>,
    /// The adjoint chain's links after the first (smooth exits only).
    pub chain: Vec<Vec<Link>>,
}

impl Walks {
    /// A wave of `slots` empty slots.
    pub fn new(slots: usize) -> Self {
        let mut rec = [0.0f32; REC];
        rec[f::L0_U + 2] = 1.0; // a harmless direction where there is no link
        Walks {
            key: vec![FREE; slots],
            walk: vec![0; slots],
            query: vec![0; slots],
            rec: vec![rec; slots],
            chain: vec![Vec::new(); slots],
        }
    }

    /// Number of slots.
    pub fn slots(&self) -> usize {
        self.key.len()
    }

    /// Starts a walk in slot `s`: travelling along `d` towards interface
    /// `key`, with throughput 1, no events, and random state `rng`; `wo` and
    /// `e_out` are the query's outgoing direction and exit (eval).
    #[allow(clippy::too_many_arguments)]
    pub fn init(
        &mut self,
        s: usize,
        key: u16,
        walk: u32,
        query: u32,
        d: [f32; 3],
        wo: [f32; 3],
        e_out: f32,
        rng: [u32; 4],
        hero: f32,
    ) {
        self.key[s] = key;
        self.walk[s] = walk;
        self.query[s] = query;
        let r = &mut self.rec[s];
        r[f::D..f::D + 3].copy_from_slice(&d);
        r[f::WO..f::WO + 3].copy_from_slice(&wo);
        r[f::E_OUT] = e_out;
        r[f::BETA..f::BETA + 3].fill(1.0);
        r[f::RATIOS..f::RATIOS + 3].fill(1.0);
        r[f::ACC..f::ACC + 3].fill(0.0);
        r[f::EVENTS] = 0.0;
        r[f::ORDER] = 0.0;
        r[f::FIRST] = 1.0;
        r[f::SPECULAR] = 1.0;
        r[f::Z] = 0.0;
        r[f::HERO] = hero;
        r[f::LINKS] = 0.0;
        for (k, v) in rng.into_iter().enumerate() {
            r[f::RNG + k] = f32::from_bits(v);
        }
        self.chain[s].clear();
    }

    /// Appends a further link to slot `s`'s chain.
    pub fn push_link(&mut self, s: usize, k: Link) {
        self.chain[s].push(k);
        self.rec[s][f::LINKS] += 1.0;
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
    /// Links in the adjoint chain.
    pub links: W,
    /// The chain's first link.
    pub link0: LinkLanes<W>,
    /// The query's outgoing direction (eval).
    pub wo: V3<W>,
    /// The query's exit interface (eval).
    pub e_out: W,
}

/// Which stage a chunk is loaded for: each loads and stores only the blocks
/// of the record it uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// An interface event (`eval`: with the adjoint chain and contribution).
    Interface {
        /// The walks connect to the viewer.
        eval: bool,
    },
    /// A layer event.
    Layer {
        /// The walks connect to the viewer.
        eval: bool,
    },
    /// Starting walks (hero channel, adjoint chain): everything.
    Launch,
}

impl Stage {
    /// Fields loaded: always blocks 0–1; layer events and eval add block 2;
    /// eval adds the chain's first link.
    fn loads(self) -> usize {
        match self {
            Stage::Interface { eval: false } => f::RATIOS,
            Stage::Layer { eval: false } => f::L0_U,
            Stage::Interface { eval: true } | Stage::Layer { eval: true } | Stage::Launch => f::END,
        }
    }
    /// Fields stored (only a launch writes the chain's first link).
    fn stores(self) -> usize {
        match self {
            Stage::Launch => f::END,
            _ => self.loads().min(f::L0_U),
        }
    }
}

/// The fields `0..hi` of the chunk's records, in lanes (rounded up to whole
/// blocks of `W::LANES` fields).
struct Fields<W: Wide>([W; REC]);

impl<W: Wide> Fields<W> {
    #[inline(always)]
    fn load(ws: &Walks, idx: &[u32], hi: usize) -> Self {
        let mut v = [W::zero(); REC];
        for first in (0..hi).step_by(W::LANES) {
            W::load_block(&ws.rec, idx, first, &mut v[first..first + W::LANES]);
        }
        Fields(v)
    }
    #[inline(always)]
    fn store(&self, ws: &mut Walks, idx: &[u32], hi: usize) {
        for first in (0..hi).step_by(W::LANES) {
            W::store_block(&self.0[first..first + W::LANES], &mut ws.rec, idx, first);
        }
    }
    #[inline(always)]
    fn v3(&self, at: usize) -> V3<W> {
        V3::new(self.0[at], self.0[at + 1], self.0[at + 2])
    }
    #[inline(always)]
    fn rgb(&self, at: usize) -> Rgb<W> {
        Rgb::new(self.0[at], self.0[at + 1], self.0[at + 2])
    }
    #[inline(always)]
    fn put3(&mut self, at: usize, x: [W; 3]) {
        self.0[at..at + 3].copy_from_slice(&x);
    }
}

impl<W: Wide> Chunk<W> {
    /// Loads slots `idx` (exactly `W::LANES` entries; lanes beyond `active`
    /// repeat the first slot and are overwritten by it on the way back).
    #[inline(always)]
    pub fn gather(ws: &Walks, idx: &[u32], active: W::Mask, stage: Stage) -> Self {
        let x = Fields::<W>::load(ws, idx, stage.loads());
        let half = W::splat(0.5);
        Chunk {
            active,
            z: x.0[f::Z],
            d: x.v3(f::D),
            beta: x.rgb(f::BETA),
            ratios: x.rgb(f::RATIOS),
            hero: x.0[f::HERO],
            events: x.0[f::EVENTS],
            order: x.0[f::ORDER],
            first: x.0[f::FIRST].gt(half),
            specular: x.0[f::SPECULAR].gt(half),
            acc: x.rgb(f::ACC),
            rng: LaneRng::from_bits(std::array::from_fn(|k| x.0[f::RNG + k].to_bit_lanes())),
            links: x.0[f::LINKS],
            link0: LinkLanes {
                conn: Connection {
                    u: x.v3(f::L0_U),
                    v: x.rgb(f::L0_V),
                    mis_pdf: x.0[f::L0_MIS],
                },
                t: x.rgb(f::L0_T),
                layer: x.0[f::L0_LAYER],
                start: x.0[f::L0_START],
            },
            wo: x.v3(f::WO),
            e_out: x.0[f::E_OUT],
        }
    }

    /// Stores the chunk back (every lane; see [`Wide::store_block`]).
    #[inline(always)]
    pub fn scatter(&self, ws: &mut Walks, idx: &[u32], stage: Stage) {
        let flag = |m: W::Mask| W::select(m, W::one(), W::zero());
        let mut x = Fields::<W>([W::zero(); REC]);
        x.put3(f::D, [self.d.x, self.d.y, self.d.z]);
        x.put3(f::BETA, [self.beta.r, self.beta.g, self.beta.b]);
        x.0[f::EVENTS] = self.events;
        x.0[f::SPECULAR] = flag(self.specular);
        for (k, b) in self.rng.to_bits().into_iter().enumerate() {
            x.0[f::RNG + k] = W::from_bit_lanes(b);
        }
        x.0[f::FIRST] = flag(self.first);
        x.0[f::HERO] = self.hero;
        x.0[f::ORDER] = self.order;
        x.0[f::Z] = self.z;
        x.put3(f::RATIOS, [self.ratios.r, self.ratios.g, self.ratios.b]);
        x.put3(f::ACC, [self.acc.r, self.acc.g, self.acc.b]);
        x.0[f::LINKS] = self.links;
        let k = &self.link0;
        x.put3(f::L0_U, [k.conn.u.x, k.conn.u.y, k.conn.u.z]);
        x.put3(f::L0_V, [k.conn.v.r, k.conn.v.g, k.conn.v.b]);
        x.0[f::L0_MIS] = k.conn.mis_pdf;
        x.0[f::L0_LAYER] = k.layer;
        x.put3(f::L0_T, [k.t.r, k.t.g, k.t.b]);
        x.0[f::L0_START] = k.start;
        x.put3(f::WO, [self.wo.x, self.wo.y, self.wo.z]);
        x.0[f::E_OUT] = self.e_out;
        x.store(ws, idx, stage.stores());
    }

    /// The lanes set in `m`.
    #[inline]
    pub fn lanes(m: W::Mask) -> impl Iterator<Item = usize> {
        let bits = W::bitmask(m);
        (0..W::LANES).filter(move |j| bits & (1 << j) != 0)
    }
}

/// True if no lane of `m` is set.
#[inline]
pub fn none<W: Wide>(m: W::Mask) -> bool {
    !m.any()
}
