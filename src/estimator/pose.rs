//! The pose between exact nodes: the model reads the height, R + F₀·dir per kilogram and
//! c_x·r_m·tan λ of its count from a segment interpolated between two exact poses, the segments
//! kept in a small ring, their neighbours prepared off the step's path, and the node spacing
//! chosen per configuration within a tenth of the budgets (docs/model.md "Pose between nodes").

use super::{Estimator, LOAD_MAX};
use crate::model::friction::CompiledLaw;
use crate::model::geometry::Geometry;
use crate::model::screw::ScrewModel;
use crate::units::{narrow, Metres, Ratio, Q};

/// The pose values the per-tick model reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct FastPose {
    pub(super) height: Metres,
    /// g_n·(cos α + 2μ_b·dir)/sin α in Q23 N/kg (≤ 235.4): R + F₀·dir per kilogram of load.
    pub(super) g: i32,
    /// c_x(α)·r_m·tan λ in Q20 ([`PoseCtx::damping_lead`]).
    pub(super) cxl: i32,
    pub(super) clamped: bool,
}

/// The pose between two exact nodes, at counts `index·2^k` and `(index + 1)·2^k`
/// (k = [`Estimator`]'s `pose_shift`): the height, R + F₀·dir per kilogram of load as
/// g_n·cos α/sin α + dir·g_n·2μ_b/sin α, and c_x·r_m·tan λ, interpolated linearly in the count (docs/model.md "Pose
/// between nodes"). cos α is linear in the count (Eq 1), so only the curvature of h and g in
/// cos α costs accuracy; k is chosen per configuration so that it stays within a tenth of the
/// budgets ([`PoseCtx::choose_pose_shift`]). A segment that touches the clamp band's edges,
/// 1/sin α's saturation (below ≈ 7.2°) or a row of Table 1 (where c_x's slope changes) is
/// `exact`: the exact pose at the count. Only what the step reads: the nodes themselves
/// (cos α, unusable) serve the classification, when the segment is filled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct PoseSegment {
    /// The segment's index (count >> k); [`NO_NODE`] in an empty slot.
    index: i32,
    exact: bool,
    /// The values ([`NODE_HEIGHT`], [`NODE_G`], [`NODE_PIN`], [`NODE_CXL`], raw bits) at the
    /// segment's start, and their rise from start to end.
    v0: [i32; 4],
    dv: [i32; 4],
}

/// Indices into a segment's values.
/// Height, Q24 m.
const NODE_HEIGHT: usize = 0;
/// g_n·cos α/sin α, Q23 N/kg.
const NODE_G: usize = 1;
/// g_n·2μ_b/sin α, Q23 N/kg.
const NODE_PIN: usize = 2;
/// c_x·r_m·tan λ, Q20 N per rad/s.
const NODE_CXL: usize = 3;

/// An exact node: [`PoseSegment`]'s four values, cos α (for Table 1's rows), whether it is
/// unusable (clamped, saturated, beyond i32 counts), whether the pose was clamped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Node {
    v: [i32; 4],
    cos: i32,
    bad: bool,
    clamped: bool,
}

impl Node {
    /// Beyond i32 counts: unusable.
    pub(super) const BAD: Node = Node {
        v: [0; 4],
        cos: 0,
        bad: true,
        clamped: true,
    };
}

impl PoseSegment {
    /// Value `j` at the Q31 fraction `f` of the segment: v0 + dv·f, the high word of dv·f
    /// being half the rise (1 LSB of rounding).
    #[inline(always)]
    fn at(&self, f: i32, j: usize) -> i32 {
        self.v0[j] + ((((i64::from(self.dv[j]) * i64::from(f)) >> 32) as i32) << 1)
    }

    /// An empty slot: no segment's index where nodes are used (k ≥ 1: indices are counts >> k).
    /// With k = 0 the count i32::MIN matches it, and every segment is exact then, as this.
    pub(super) const EMPTY: PoseSegment = PoseSegment {
        index: NO_NODE,
        exact: true,
        v0: [0; 4],
        dv: [0; 4],
    };
}

/// The tag of an empty segment slot or node slot: no segment's index or boundary where nodes
/// are used (counts >> k, k ≥ 1).
pub(super) const NO_NODE: i32 = i32::MIN;

/// Standard gravity in Q16 m/s² (as [`Geometry::weight`]).
const G_N_Q16: i64 = 642_689;

/// Interpolation error of the height allowed between nodes, a tenth of its budget
/// (docs/model.md): 5 µm (Q24 m). R + F₀·dir: [`PoseBudget`].
const POSE_HEIGHT_TOL: i32 = 84; // 5·10⁻⁶·2^24
/// The operating envelope T_r's budget holds over (docs/model.md "Pose between
/// nodes"): |θ̇| ≤ 400 rad/s, |θ̈| ≤ 2000 rad/s² (the twin proptests' range), load ≤
/// [`LOAD_MAX`] (2× the largest rated load a configuration accepts, 5 t).
const BUDGET_SPEED: u32 = 400;
const BUDGET_ACCEL: u64 = 2000;
/// A tenth of T_r's budget: 0.5 mN·m/10 = 5·10⁻⁵ N·m (×2^32, rounded down), and 0.2 %/10 =
/// 1/5000.
const TORQUE_FLOOR_TENTH_Q32: u64 = 214_748;
const REL_TENTH_INV: u64 = 5000;
/// Most segments the spacing search walks over all the spacings it tries (the default lift: 630;
/// ≤ 3·8192 poses, ≈ 5 M instructions at configuration time).
const POSE_WALK_MAX: u32 = 8192;
/// Largest node spacing tried, 2^16 counts.
const POSE_SHIFT_MAX: u32 = 16;

/// What the error of W's pose term may be, so that T_r (and the thread torque) stays within a
/// tenth of its budget, max(0.2 %·|T_r|, 0.5 mN·m), over the operating envelope (docs/model.md
/// "Pose between nodes"). W = M·G(dir) + D with G(dir) = R + F₀·dir per kilogram (the
/// interpolated term) and |D| ≤ c_x·r_m·tan λ·400 + m·r_m·tan λ·2000 (damping and inertia at the
/// envelope's bounds); T_r and the thread torque move by at most K·ΔW, K = r_m·(tan λ + μ_hi)/
/// (1 − μ_hi·tan λ) with μ_hi the law's largest μ over the envelope's speeds. An error e of
/// G(dir) per kilogram is within a tenth of the budget for every load M ≤ [`LOAD_MAX`] if
/// (1) e·LOAD_MAX ≤ A = 5·10⁻⁵ N·m/K (the absolute floor's tenth, at the heaviest load), or
/// (2) e·(5000·A + D) ≤ A·|G(dir)| (for M·e ≤ A the floor holds; for larger M,
/// |W| ≥ M·|G| − D ≥ (A/e)·|G| − D, and then M·e ≤ |W|/5000).
pub(super) struct PoseBudget {
    /// A in Q24 N.
    a: u64,
    /// The largest e (Q23 N/kg) that passes (1): e·2^-23·`LOAD_MAX` ≤ A.
    e_abs: u32,
    /// 5000·A + m·r_m·tan λ·2000 (D's inertial part), Q24 N.
    c0: u64,
}

impl PoseBudget {
    /// In u64: every quantity below is bounded, and 128-bit products and quotients expand into
    /// long code on the board.
    pub(super) fn new(screw: &ScrewModel, law: &CompiledLaw, mass_lead_q32: i32) -> PoseBudget {
        // μ_hi ≥ μ(x) for |θ̇| ≤ 400 rad/s (law input x, Q16): μ = base + amp·e^(−y) +
        // lin(min(x, x_max)) with 0 < e^(−y) ≤ 1 and lin linear, so μ ≤ max(amp, 0) +
        // max(base, μ(x_400) + max(−amp, 0)) (base + lin at either end of the range).
        let given = law.law();
        let amp = i64::from(given.amp.bits());
        let end = i64::from(law.mu_unfloored_call(BUDGET_SPEED << 16));
        let mu_hi = (amp.max(0) + i64::from(given.base.bits()).max(end + (-amp).max(0)))
            .min(i64::from(screw.mu_max().bits()))
            .max(0) as u64; // not `clamp`: its min ≤ max check pulls a formatted panic
        let tan = screw.tan_lambda().bits() as u64;
        // K = r_m·num/den (Q24·Q28/Q28); μ_hi·tan λ ≤ 1/3 (`mu_max`): den ≥ ⅔·2^28.
        let num = tan + mu_hi;
        let den = (1u64 << 28) - (mu_hi * tan >> 28);
        let r = screw.pitch_radius().bits() as u64;
        // A·2^24 = 5·10⁻⁵·2^32·2^16·den/(r_q24·num) (numerator < 2^62): ≤ 2^27 (r_m ≥ 1 mm,
        // tan λ ≥ tan 0.5°), ≥ 2^11 (r_m ≤ 5 cm, μ_hi ≤ 4).
        let a = (TORQUE_FLOOR_TENTH_Q32 << 16) * den / (r * num);
        let load_max = u64::from(LOAD_MAX.bits() as u32 >> 12);
        PoseBudget {
            a,
            e_abs: (a / (2 * load_max)) as u32,
            // mass_lead ≥ 0 (Q32 → Q24): < 2^34; 5000·A < 2^40.
            c0: REL_TENTH_INV * a + (u64::from(mass_lead_q32 as u32) * BUDGET_ACCEL >> 8),
        }
    }

    /// Whether an interpolation error `e` of G(dir) (Q23 N/kg) at a pose whose G(dir) is `g`
    /// and c_x·r_m·tan λ is `cxl` (Q20 N per rad/s) keeps T_r within a tenth of its budget.
    fn holds(&self, e: i32, g: i32, cxl: i32) -> bool {
        let e = e.unsigned_abs();
        if e <= self.e_abs {
            return true;
        }
        // (2) fails beyond |G|/5000 < 2^19; below 2^20 the products fit: D = c_x·lead·400
        // (Q20 → Q24) < 2^43, c0 < 2^41, A·|G| < 2^58.
        let d = u64::from(cxl.unsigned_abs()) * u64::from(BUDGET_SPEED) << 4;
        e < 1 << 20 && u64::from(e) * (self.c0 + d) <= self.a * u64::from(g.unsigned_abs())
    }

    /// Whether G's error bound `e` (|ΔG₀| + |ΔG_b|, falling as α grows) passes (1): then every
    /// segment above passes.
    fn absolute_holds(&self, e: i32) -> bool {
        e.unsigned_abs() <= self.e_abs
    }
}

/// What the pose segments need of the estimator's configuration (borrowed): also usable
/// while `Estimator::new` is still choosing the node spacing, so that the estimator is built
/// once, in its caller's slot (a local adjusted and then moved into `Ok` would be a second
/// copy of the estimator on the frame of every caller of `new`).
pub(super) struct PoseCtx<'a> {
    pub(super) geometry: &'a Geometry,
    pub(super) two_mu_pin: Ratio,
    pub(super) damping_lead: &'a [(i32, i32, i32); 3],
    pub(super) pose_shift: u32,
    pub(super) pose_frac: u32,
}

/// [`PoseCtx`] of an estimator, built field by field: usable where a method's `&self` could not
/// be, beside a mutable borrow of the segment state ([`Estimator::refill_slot`],
/// [`Estimator::prepare`]).
macro_rules! pose_ctx {
    ($e:expr) => {
        PoseCtx {
            geometry: &$e.geometry,
            two_mu_pin: $e.two_mu_pin,
            damping_lead: &$e.damping_lead,
            pose_shift: $e.pose_shift,
            pose_frac: $e.pose_frac,
        }
    };
}

impl Estimator {
    /// The pose segments' view of this estimator.
    #[inline(always)]
    pub(super) fn pose_ctx(&self) -> PoseCtx<'_> {
        pose_ctx!(self)
    }

    /// The slot of segment `index` (`index & 3`), refilled first unless it holds that segment
    /// (a neighbour [`Self::prepare`] filled, or the last step's): the step's one check.
    #[inline(always)]
    pub(super) fn track_segment(&mut self, index: i32) -> usize {
        let slot = (index & 3) as usize;
        if self.segments[slot].index != index {
            self.refill_slot(index);
        }
        slot
    }

    /// The segment `index` filled into its slot from its two nodes, those not in the node
    /// ring computed (exact poses): the step's fallback when the count enters a segment that is
    /// not prepared (the first step, a jump, `prepare` not called or not done yet).
    #[inline(never)]
    fn refill_slot(&mut self, index: i32) {
        self.prepared = NO_NODE;
        while !self.fill_piece(index) {}
    }

    /// One piece of filling segment `j`'s slot: a node at its start or end missing from the
    /// ring computed (false), or both there and the segment filled from them (true; with k = 0
    /// no nodes: exact). Out of line: the step's refill and `prepare` share one copy.
    #[inline(never)]
    fn fill_piece(&mut self, j: i32) -> bool {
        let ctx = pose_ctx!(self);
        let s0 = (j & 3) as usize;
        if ctx.pose_shift == 0 {
            ctx.refill(&mut self.segments[s0], j);
            return true;
        }
        // k ≥ 1: j + 1 stays in i32.
        let s1 = ((j + 1) & 3) as usize;
        let b = if self.node_tags[s0] != j {
            j
        } else if self.node_tags[s1] != j + 1 {
            j + 1
        } else {
            ctx.fill(&mut self.segments[s0], j, &self.nodes[s0], &self.nodes[s1]);
            return true;
        };
        let s = (b & 3) as usize;
        self.nodes[s] = ctx.node_at(b);
        self.node_tags[s] = b;
        false
    }

    /// One bounded piece of the pose segments' preparation, off the step's path: for the
    /// segments on either side of the last step's count (the one in the direction of motion
    /// first), one missing exact node (≈ the cost of one exact pose), or one segment filled from
    /// its two nodes (differences and classification). Returns at once when both neighbours
    /// are ready, as it does with k = 0 (no nodes). After it has run on the two or four ticks
    /// following a crossing, a step whose count enters either neighbour reads it as it reads
    /// its own segment: no exact pose on the step. Skipping it is safe: the step then refills
    /// the segment it enters (`refill_slot`), the same bits more slowly.
    ///
    /// Call it once a tick after the tick's outputs are applied
    /// ([`crate::control::Controller::finish_tick`]), so that the node work of a crossing does
    /// not delay them.
    #[inline(never)]
    pub fn prepare(&mut self) {
        let k = self.pose_shift;
        let i = self.last_counts >> k;
        if i == self.prepared || k == 0 {
            return;
        }
        // The neighbour in the direction of motion first (k ≥ 1: indices ± 2 stay in i32).
        let d = if self.v < 0 { -1 } else { 1 };
        let missing = |e: &Estimator, j: i32| e.segments[(j & 3) as usize].index != j;
        let j = if missing(self, i + d) {
            i + d
        } else if missing(self, i - d) {
            i - d
        } else {
            self.prepared = i;
            return;
        };
        self.fill_piece(j);
    }

    /// G_d = (R + F₀·d)/M at `counts` in direction `dir`, Q23 N/kg: the axial force per
    /// kilogram on the head, as the step's model evaluates it (from the pose segment holding
    /// `counts`, or the exact pose where no prepared segment does). With a step's
    /// `thread_torque` and `axial`, the load identification's gain ∂T/∂M (`crate::ident`),
    /// which reads it once per window: out of the step.
    #[inline(never)]
    pub fn g_per_kg(&self, counts: i32, dir: i8) -> i32 {
        let index = counts >> self.pose_shift;
        let seg = &self.segments[(index & 3) as usize];
        if seg.index == index {
            self.pose_on(seg, counts, dir).g
        } else {
            self.exact_pose(counts, dir).g
        }
    }

    /// [`PoseCtx::exact_pose`] for this estimator.
    #[inline(never)]
    pub(super) fn exact_pose(&self, counts: i32, dir: i8) -> FastPose {
        self.pose_ctx().exact_pose(counts, dir)
    }

    /// The model's pose at `counts` for direction `dir` on `seg` (the segment holding it).
    #[inline(always)]
    pub(super) fn pose_on(&self, seg: &PoseSegment, counts: i32, dir: i8) -> FastPose {
        if seg.exact {
            return self.exact_pose(counts, dir);
        }
        let f = fraction(self.pose_frac, counts);
        let at = |j: usize| seg.at(f, j);
        FastPose {
            height: Metres::from_raw(at(NODE_HEIGHT)),
            // |g_n·2μ_b/sin α| ≤ 157 N/kg (Q23 < 2^31): the sum stays within ±235.4.
            g: at(NODE_G) + i32::from(dir) * at(NODE_PIN),
            cxl: at(NODE_CXL),
            clamped: false,
        }
    }
}

/// The position of `counts` within its segment as a Q31 fraction, for `frac` = 2^(32−k): the
/// count's low k bits on top (a product: one `MUL`, where a variable shift is masked first).
#[inline(always)]
fn fraction(frac: u32, counts: i32) -> i32 {
    ((counts as u32).wrapping_mul(frac) >> 1) as i32
}

impl PoseCtx<'_> {
    /// (G₀, G_b) = (g_n·cos α/sin α, g_n·2μ_b/sin α) in Q23 N/kg for an exact pose's cos α and
    /// 1/sin α (Q28): g_n/sin α first (Q23, ≤ 8·9.81 < 2^30), then one product each (cos α ≤ 1,
    /// 2μ_b ≤ 2 in Q28): |G₀ ± G_b| ≤ 3·8·9.81 < 2^31 in Q23.
    #[inline(always)]
    fn g_parts(&self, cos: i32, inv_sin: i32) -> (i32, i32) {
        let g_inv = (i64::from(inv_sin) * G_N_Q16) >> 21;
        let part = |x: i32| ((g_inv * i64::from(x)) >> 28) as i32;
        (part(cos), part(self.two_mu_pin.bits()))
    }

    /// The exact node at `counts`: the pose's height, cos α and 1/sin α (one scale and one
    /// √/1/√ kernel, [`Geometry::pose_node`]), G₀ and G_b (three products) and Table 1's
    /// c_x·lead. Out of line: the segment's fill, the exact segments and the
    /// configuration-time spacing search share it (the search validates these nodes).
    #[inline(never)]
    fn pose_node(&self, counts: i32) -> Node {
        let (height, cos_alpha, inv_sin, clamped) = self.geometry.pose_node(counts);
        let (cos, inv) = (cos_alpha.bits(), inv_sin.bits());
        let (g0, gb) = self.g_parts(cos, inv);
        Node {
            v: [height.bits(), g0, gb, self.damping_lead(cos_alpha)],
            cos,
            bad: clamped || inv == i32::MAX,
            clamped,
        }
    }

    /// The node at segment boundary `i` (count i·2^k); unusable beyond i32 counts. Out of
    /// line: the refills and `prepare` share one copy.
    #[inline(never)]
    fn node_at(&self, i: i32) -> Node {
        // i·2^k in i32 iff shifting back gives i (k ≤ 16): no 64-bit shift.
        let c = i.wrapping_shl(self.pose_shift);
        if c >> self.pose_shift == i {
            self.pose_node(c)
        } else {
            Node::BAD
        }
    }

    /// `seg` filled for the segment `index`, in place, from two exact nodes computed here
    /// (`estimate`, the spacing search; the estimator's slots keep their nodes,
    /// [`Estimator::refill_slot`]). A function of `index` alone: the nodes are exact poses at
    /// fixed counts.
    #[inline(never)]
    pub(super) fn refill(&self, seg: &mut PoseSegment, index: i32) {
        if self.pose_shift == 0 {
            seg.index = index;
            seg.exact = true;
            return;
        }
        let n0 = self.node_at(index);
        let n1 = self.node_at(index.saturating_add(1));
        self.fill(seg, index, &n0, &n1);
    }

    /// `seg` for the segment `index` between nodes `n0`, `n1`: the start's values, their rise
    /// and whether it is evaluated exactly: an unusable node, a row of Table 1 strictly inside
    /// (cos α falls along the segment: c_x's slope changes there), or below count 0 (α₀ − 5° …
    /// α₀, outside the envelope the spacing is checked over). Out of line: the refill, the
    /// slot's refill and `prepare` share one copy.
    #[inline(never)]
    fn fill(&self, seg: &mut PoseSegment, index: i32, n0: &Node, n1: &Node) {
        seg.index = index;
        seg.v0 = n0.v;
        // Nodes within the band: heights ≤ 3 m, |G| ≤ 235.4 (Q23), c_x·r_m·tan λ < 2^30: the
        // differences of usable nodes fit (an unusable one is never interpolated).
        seg.dv = core::array::from_fn(|j| n1.v[j].wrapping_sub(n0.v[j]));
        let kink = self
            .damping_lead
            .iter()
            .any(|&(c, _, _)| c < n0.cos && c > n1.cos);
        seg.exact = n0.bad || n1.bad || kink || index < 0;
    }

    /// The exact pose's values (segments at the band's edges and Table 1's rows, coarse
    /// encoders): the node's values at the count, the same arithmetic. Out of line: inlined,
    /// it cost the step's common path ≈ 25 instructions of register moves.
    #[inline(always)]
    fn exact_pose(&self, counts: i32, dir: i8) -> FastPose {
        let n = self.pose_node(counts);
        FastPose {
            height: Metres::from_raw(n.v[NODE_HEIGHT]),
            g: n.v[NODE_G] + i32::from(dir) * n.v[NODE_PIN],
            cxl: n.v[NODE_CXL],
            clamped: n.clamped,
        }
    }

    /// 2^(32 − k) for a node spacing 2^k (k ≥ 1), 0 for k = 0.
    pub(super) fn frac_for(k: u32) -> u32 {
        if k == 0 {
            0
        } else {
            1u32 << (32 - k)
        }
    }

    /// The largest node spacing 2^k (k ≤ [`POSE_SHIFT_MAX`]) whose interpolation keeps the
    /// height within [`POSE_HEIGHT_TOL`] and T_r within a tenth of its budget ([`PoseBudget`]),
    /// checked at the midpoint of every usable segment from α₀ (count 0) up, where a segment's
    /// interpolation error peaks, for dir −1, 0, +1, until the error bound |ΔG₀| + |ΔG_b| passes
    /// the absolute test (1) on at least four segments. The curvatures of h, G₀ and G_b in cos α
    /// (1/sin³ α; 3 cos α/sin⁵ α; (1 + 2 cos² α)/sin⁵ α) fall as α grows, and cos α is linear
    /// in the count, so every segment above passes (1) and the height. 0 if none passes.
    /// Configuration time: three poses per segment walked (the default lift: 621 segments for
    /// the k it takes, ≈ 1 860 poses; a few for each larger k, which fail at α₀), at most
    /// [`POSE_WALK_MAX`] segments in all, beyond which it returns 0. The end node is
    /// not carried to the next segment: it would save a third of them for more code and a
    /// larger frame on the console task's stack. Out of line: its frame is not on `new`'s while the law's table
    /// is built.
    #[inline(never)]
    pub(super) fn choose_pose_shift(&mut self, budget: &PoseBudget) -> u32 {
        let mut walk = POSE_WALK_MAX;
        'k: for k in (1..=POSE_SHIFT_MAX).rev() {
            self.pose_shift = k;
            self.pose_frac = Self::frac_for(k);
            // From the segment at α₀ (count 0; those below are exact), past any exact ones
            // (Table 1's rows), up to the band's top (indices < 2^31 >> k: no wrap).
            let mut seg = PoseSegment::EMPTY;
            let mut checked = 0;
            let mut index = 0i32;
            while index < i32::MAX >> k {
                // Configuration time stays bounded whatever the configuration: past the walk's
                // allowance, the exact pose at every count (always within the budgets).
                walk -= 1;
                if walk == 0 {
                    return 0;
                }
                self.refill(&mut seg, index);
                if seg.exact && self.node_at(index).bad {
                    break;
                }
                if !seg.exact {
                    // The midpoint, where a segment's interpolation error peaks.
                    let c = (index << k) + (1 << (k - 1));
                    let want = self.pose_node(c).v;
                    let f = fraction(self.pose_frac, c);
                    let err = |j: usize| seg.at(f, j) - want[j];
                    if err(NODE_HEIGHT).abs() > POSE_HEIGHT_TOL {
                        continue 'k;
                    }
                    for dir in [-1, 0, 1] {
                        let e = err(NODE_G) + dir * err(NODE_PIN);
                        if !budget.holds(e, want[NODE_G] + dir * want[NODE_PIN], want[NODE_CXL]) {
                            continue 'k;
                        }
                    }
                    checked += 1;
                    if checked >= 4
                        && budget.absolute_holds(err(NODE_G).abs() + err(NODE_PIN).abs())
                    {
                        break;
                    }
                }
                index += 1;
            }
            if checked > 0 {
                return k;
            }
        }
        0
    }

    /// c_x(α)·r_m·tan λ (Q20, N per rad/s) at the pose with cosine `cos_alpha`: Table 1 as
    /// [`Geometry::structure_damping`] interpolates it (linear in cos α between its angles,
    /// flat outside), times the lead.
    #[inline(always)]
    fn damping_lead(&self, cos_alpha: Ratio) -> i32 {
        let t = &self.damping_lead;
        let c = cos_alpha.bits();
        if c >= t[0].0 {
            return t[0].1;
        }
        let i = if c >= t[1].0 {
            0
        } else if c >= t[2].0 {
            1
        } else {
            return t[2].1;
        };
        // Within a segment: |Δcos·slope| ≤ |Δc|·2^24, so the sum stays between two entries.
        narrow(i64::from(t[i].1) + ((i64::from(t[i].0 - c) * i64::from(t[i].2)) >> 24))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::{EstimatorConfig, Measurements};
    use crate::units::{Amperes, Instant, Kilograms};
    use fixed::types::I16F16;

    /// Configurations of very different node spacings: the default lift, a long lift at a
    /// low α₀ with a fine encoder, a short one at a high α₀ with a coarse encoder and a big
    /// screw, and heavy pin friction.
    fn configs() -> [EstimatorConfig; 4] {
        let d = EstimatorConfig::DEFAULT;
        let mut fine = d;
        fine.geometry.length = Metres::lit("2");
        fine.geometry.alpha0_deg = I16F16::lit("12");
        fine.geometry.alpha_max_deg = I16F16::lit("89");
        fine.drive.counts_per_rev = 4096;
        fine.drive.gear_ratio = I16F16::lit("100");
        let mut coarse = d;
        coarse.geometry.length = Metres::lit("0.05");
        coarse.geometry.alpha0_deg = I16F16::lit("60");
        coarse.geometry.alpha_max_deg = I16F16::lit("89");
        coarse.drive.counts_per_rev = 4;
        coarse.drive.gear_ratio = I16F16::lit("1");
        coarse.drive.pitch_radius = Metres::lit("0.05");
        coarse.drive.lead_angle_deg = I16F16::lit("20");
        let mut pins = d;
        pins.geometry.mu_pin = Ratio::ONE;
        [d, fine, coarse, pins]
    }

    /// Over the whole stroke (α₀ to the band's top, 4096 positions), the pose the model reads
    /// between nodes is within the tolerances the node spacing was chosen for, for both
    /// directions: the curvature falls as α grows, so the segments checked at α₀ bound all the
    /// others. Also: the same bits from a fresh segment as from a walked one (the nodes are
    /// functions of the count).
    #[test]
    fn the_pose_between_nodes_stays_within_its_tolerances_over_the_stroke() {
        for cfg in configs() {
            let mut est = Estimator::new(&cfg).unwrap();
            let k = est.pose_shift();
            let budget = PoseBudget::new(&est.screw, &est.law, est.mass_lead_q32);
            // The band's top: the first clamped count above 0.
            let (mut lo, mut hi) = (0i64, i64::from(i32::MAX));
            while hi - lo > 1 {
                let mid = (lo + hi) / 2;
                if est.geometry.pose(mid as i32).clamped {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            let top = lo as i32;
            let mut interpolated = 0;
            let mut neighbour = 0;
            // Up the stroke and back down, as the steps track the segment and `prepare` runs
            // between them (neighbours entered prepared: counted, and the same bits as a
            // fresh fill).
            for i in (0..4096i64).chain((0..4096).rev()) {
                let c = (i64::from(top) * i / 4096) as i32;
                let index = c >> k;
                let moved = index != est.last_counts >> k;
                neighbour +=
                    usize::from(moved && est.segments[(index & 3) as usize].index == index);
                let slot = est.track_segment(index);
                est.last_counts = c;
                // Enough calls for both neighbours (two nodes and two fills at most).
                for _ in 0..5 {
                    est.prepare();
                }
                let fresh = |j: i32| {
                    let mut seg = PoseSegment::EMPTY;
                    est.pose_ctx().refill(&mut seg, j);
                    seg
                };
                assert_eq!(fresh(index), est.segments[slot], "{c}");
                if k > 0 {
                    assert_eq!(est.prepared, index, "{c}");
                    for j in [index - 1, index + 1] {
                        assert_eq!(fresh(j), est.segments[(j & 3) as usize], "{c} {j}");
                    }
                }
                let seg = est.segments[slot];
                let exact = est.geometry.pose(c);
                let (cos, inv) = (exact.cos_alpha.bits(), exact.inv_sin_alpha.bits());
                let ctx = est.pose_ctx();
                let (g0, gb) = ctx.g_parts(cos, inv);
                let cxl = ctx.damping_lead(exact.cos_alpha);
                for dir in [-1i8, 0, 1] {
                    let got = est.pose_on(&seg, c, dir);
                    let dh = (got.height.bits() - exact.height.bits()).abs();
                    let g = g0 + i32::from(dir) * gb;
                    // The budget's test, with 4 LSB of rounding to spare.
                    let dg = ((got.g - g).abs() - 4).max(0);
                    assert!(dh <= POSE_HEIGHT_TOL + 2, "{k} {c} height {dh}");
                    assert!(budget.holds(dg, g, cxl), "{k} {c} g {dg} at {g}");
                    let dc = (got.cxl - cxl).abs();
                    assert!(dc <= 4, "{k} {c} c_x {dc}");
                }
                interpolated += usize::from(!seg.exact);
            }
            // The default lift and the fine encoder interpolate nearly everywhere.
            if k >= 4 {
                assert!(interpolated > 7800, "{k}: {interpolated}");
                // Both directions enter neighbours from the nodes computed ahead.
                assert!(neighbour > 100, "{k}: {neighbour}");
            }
        }
    }

    /// A step whose count enters a neighbour [`Estimator::prepare`] filled returns the bits of
    /// a step that fills its segment from two fresh exact nodes: up and down the stroke at
    /// motion speeds, reversals on a boundary, jumps (over segments, below count 0, to the
    /// clamp band and the ends of i32), for configurations of very different node spacings.
    /// Each `prepare` does at most one piece (one node, or one segment filled).
    #[test]
    fn entering_a_prepared_neighbour_gives_the_bits_of_a_fresh_refill() {
        for cfg in configs() {
            let mut prepared = Estimator::new(&cfg).unwrap();
            let mut fresh = Estimator::new(&cfg).unwrap();
            let k = prepared.pose_shift();
            let seg = 1i32 << k;
            // Counts: a climb at 1…3 counts a tick through several segments, a reversal on a
            // boundary (back and forth across it), a descent, jumps.
            let mut counts = Vec::new();
            let b = 40 * seg;
            let mut c = b - 5 * seg / 2;
            while c < b + 3 * seg {
                counts.push(c);
                c += 1 + (c & 1) * 2;
            }
            for j in 0..12 {
                counts.push(b - 1 + (j & 1));
                counts.push(b - 1 + (j & 1));
            }
            while c > b - 3 * seg {
                counts.push(c);
                c -= 2;
            }
            counts.extend([
                b + 7 * seg,
                b + 7 * seg + 1,
                -3 * seg,
                -3 * seg - 1,
                -seg,
                0,
                1,
            ]);
            counts.extend([
                i32::MAX,
                i32::MAX - 1,
                i32::MIN,
                i32::MIN + 1,
                b,
                b + seg,
                b,
            ]);
            let mut entered = [0usize; 2];
            for (t, &c) in counts.iter().enumerate() {
                let m = Measurements {
                    position_counts: c,
                    motor_current: Amperes::lit("20"),
                    load: Kilograms::lit("1000"),
                    commanded_dir: 1,
                };
                let now = Instant(1000 * t as u32);
                let index = c >> k;
                let was = prepared.last_counts >> k;
                if t > 0 && index != was && prepared.segments[(index & 3) as usize].index == index {
                    entered[usize::from(index < was)] += 1;
                }
                // The fresh one keeps no segment or node from one step to the next.
                fresh.segments = [PoseSegment::EMPTY; 4];
                fresh.node_tags = [NO_NODE; 4];
                let (p, f) = (prepared.step(now, &m), fresh.step(now, &m));
                assert_eq!(p, f, "k={k} count {c} (step {t})");
                for _ in 0..3 {
                    let tags = (prepared.segments.map(|s| s.index), prepared.node_tags);
                    prepared.prepare();
                    let changed = (0..4)
                        .filter(|&s| prepared.segments[s].index != tags.0[s])
                        .count()
                        + (0..4)
                            .filter(|&s| prepared.node_tags[s] != tags.1[s])
                            .count();
                    assert!(
                        changed <= 1,
                        "k={k} count {c}: {changed} pieces in one call"
                    );
                }
            }
            // Both directions entered prepared neighbours (k ≥ 1 has neighbours to prepare).
            if k > 0 {
                assert!(entered[0] >= 5 && entered[1] >= 5, "k={k}: {entered:?}");
            }
        }
    }
}
