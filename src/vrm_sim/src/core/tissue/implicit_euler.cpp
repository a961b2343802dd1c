#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <new>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "integrators_impl.h"

namespace vrm_sim {
namespace tissue {
namespace {

// Implicit (backward) Euler, eqs. 5.7-5.10, linearised as in Baraff & Witkin (1998):
//   (M + Δt·c·I + Δt²·S) Δv = Δt·(F⁰ − Δt·S v⁰),   x += Δt (v⁰ + Δv)
// with S = −∂F/∂x, solved by preconditioned conjugate gradients, matrix-free. Spring s contributes the block
// B_s = Δt²k(t·I + (1 − t)·uuᵀ) = a_s·I + v_s v_sᵀ (t = max(0, 1 − l/|d|), a_s = Δt²k·t, v_s = sqrt(Δt²k(1 − t))·u):
// four numbers instead of nine. The transverse part of a compressed spring's block is clamped at zero so A stays
// positive definite — CG needs that, and it only removes buckling stiffness.
//
// Layout, chosen for the product A·p that every CG iteration runs once (issues 15 and 40):
//  - node vectors are structure of arrays [x…|y…|z…] in the nodes' own order, padded to kLanes and
//    cache-line aligned;
//  - each spring belongs to its end with the lower index; nodes are taken kLanes at a time (one SIMD lane
//    each) and their own springs slot by slot (sliced ELLPACK). A slot holds one direction (the other ends are
//    kLanes consecutive nodes: one vector load and one vector read-modify-write per component) where the group's
//    springs allow it, else each lane's k-th spring (gathered);
//  - the product reads each block once: B_s (p_i − p_j) goes to the owner's sum in registers and is subtracted from
//    the other end in q, whose group comes later in the sweep;
//  - the blocks, a node block per node (the preconditioner), the Hooke forces and Δt²·S v⁰ come from one sweep over
//    the springs at the start of a step (assemble()).
// Measured (bench_implicit, 10k nodes, idle machine, median ms per step with 10 CG iterations, Jacobi, dt 1 ms):
// 1.51 ms for the gather-only form with blocks read by both ends and a scalar block pass, 1.09 ms for this one
// (without FMA contraction, below). Each sweep then came to initialise what it writes just ahead of its first write
// (no zero and fill passes of their own): 4–5 % less in interleaved A/B runs. Where the time goes now (perf): the 10
// products 53 %, the assembly 19 %, the CG vector passes 18 %, the rest 10 %. At 10k nodes a product reads 1.5 MB
// (blocks and p, q), more than a core's 1 MB L2, yet the step's ns per node grow only 1.17× from 961 nodes (all in
// L2) to 10k; and the other ends' overlapping unaligned read-modify-writes (three per component and group on a grid)
// do not hold it either: the last two tries below remove every partial store forwarding and are slower.
// The blocks as one record per slot instead of four arrays made no difference (kept). Tried and not kept: float
// blocks (8 % faster products; CG then converges to the rounded matrix, ~1e-7 relative, and the dense-solve tests
// ask for 1e-9), one q array per slot direction modulo 3 (no overlapping stores, but 3× the q traffic: 28 % slower),
// the offset-1 slot kept in registers by a lane shift, a slot order that puts overlapping writes apart (neither
// gained), the direction update folded into the product (19 % slower: z and p loaded at every other end), the other
// ends' read-modify-writes as whole aligned vectors, t's lanes shifted into two of them (bit-identical, so that
// every store forwards whole to the next load: 20 % slower, twice the loads and stores), and those aligned vectors held
// in registers while consecutive slots write the same ones (bit-identical, no partial store forwarding left, as many
// loads and stores as now: 5–10 % slower, the lane shifts cost more than the stalls they remove). On an AMD EPYC
// (Zen 5, the AVX-512 clone; 2026-12-01, thread CPU time, alternating runs): the other ends' read-modify-writes cost
// a fifth of the step (left out, with wrong results, the step is 1.29× faster; made aligned, also wrong, 1.25×), but
// neither alignment nor forwarding is what costs: a lane-banded node order (lane l of group g = node l·⌈n/8⌉ + g, so
// 95 % of the slots' other ends are aligned vectors and every overlap is whole) was no faster, nor were t's lanes moved
// into two aligned vectors by permutes, nor each write as two 4-lane halves; and Δv += α·p, p = z + β·p applied
// just ahead of the product's first read of p, like q's zeroing, was 7 % slower than its own streaming pass.
// Constrained nodes (pinned or grasped) are handled by the filtered CG of Baraff & Witkin §5.3: their rows of A are
// zero blocks and their preconditioner is zero, so p, Δv and r stay zero on them — the "infinite mass" of the thesis
// without ill-conditioning. A step allocates nothing once the buffers have their size.

// Built for AVX-512, AVX2 and the baseline, picked at load time like spring_kernels.cpp. The file is compiled with
// -ffp-contract=off and every lane sum runs in one fixed order, so the three builds round alike and a session's state
// hash does not depend on the CPU (issue 40 §3; with FMA the step was 8 % faster).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define VRM_IMPLICIT_KERNEL __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define VRM_IMPLICIT_KERNEL
#endif

constexpr std::size_t kLanes = 8;
// A slot's blocks are one record: a, v_x, v_y, v_z, kLanes each.
constexpr std::size_t kBlockDoubles = 4 * kLanes;
// kLanes doubles (one AVX-512 register, two AVX2 ones); unaligned loads and stores through this type alias double.
typedef double Lanes __attribute__((vector_size(8 * kLanes), aligned(8), may_alias));

// Cache-line aligned storage for the arrays the sweeps read kLanes at a time: a vector at a multiple of kLanes then
// never straddles two lines.
template <typename T>
struct CacheLineAllocator {
  using value_type = T;
  static constexpr std::align_val_t kAlignment{64};
  CacheLineAllocator() = default;
  template <typename U>
  CacheLineAllocator(const CacheLineAllocator<U>&) {}
  T* allocate(std::size_t count) { return static_cast<T*>(::operator new(count * sizeof(T), kAlignment)); }
  void deallocate(T* pointer, std::size_t) { ::operator delete(pointer, kAlignment); }
  bool operator==(const CacheLineAllocator&) const { return true; }
  bool operator!=(const CacheLineAllocator&) const { return false; }
};
using AlignedDoubles = std::vector<double, CacheLineAllocator<double>>;

inline Lanes& lanes(double* base) { return *reinterpret_cast<Lanes*>(base); }
inline const Lanes& lanes(const double* base) { return *reinterpret_cast<const Lanes*>(base); }
inline double sum(const Lanes& v) {
  double total = 0.0;
  for (std::size_t lane = 0; lane < kLanes; ++lane) total += v[lane];
  return total;
}

// The kLanes values base[index[lane]].
inline Lanes gather(const double* base, const std::uint32_t* index) {
  Lanes values;
  for (std::size_t lane = 0; lane < kLanes; ++lane) values[lane] = base[index[lane]];
  return values;
}

// The blocks B_s = a·I + v vᵀ, one record per slot (a, v_x, v_y, v_z; the zero block in padding lanes), and the
// filter.
struct Springs {
  const double* blocks;
  const double* mask;  // per node: 1 free, 0 constrained (rows of A·p that are filtered out)

  void load(std::uint32_t slot, Lanes& bx, Lanes& by, Lanes& bz, Lanes& ba) const {
    const double* record = blocks + kBlockDoubles * slot;
    ba = lanes(record);
    bx = lanes(record + kLanes);
    by = lanes(record + 2 * kLanes);
    bz = lanes(record + 3 * kLanes);
  }
};

// The node-ordered spring structure; depends on the topology only. Nodes keep their own indices: a mesh built row by
// row (the grid membranes) keeps its rows, so a group's springs point the same ways (sorted by degree instead, the
// border nodes moved to the end and every group next to the border gathered: 40 % of the product's time at 10k
// nodes). Each spring belongs to the end with the lower index (its owner). Nodes are taken kLanes at a time (a group)
// and their own springs slot by slot: a slot holds one offset (other end − node) where the group's springs take few
// enough offsets, so in a regular patch its kLanes other ends are consecutive nodes (lanes without that spring hold the
// zero block); else slot k holds each lane's k-th spring and the other ends are gathered.
struct Structure {
  std::size_t nodes = 0, padded = 0, springs = 0;
  std::vector<std::array<std::uint32_t, 2>> ends;  // copy of the spring ends it was built from
  std::vector<std::uint32_t> group_slots;          // first slot of group g; group_slots[groups] = slot count
  std::vector<std::uint32_t> reach;                // per group: end of the nodes groups 0..g touch (a kLanes multiple)
  std::vector<std::int32_t> first_neighbour;       // per slot: other end of lane 0 if the lanes' are consecutive
  std::vector<std::uint32_t> neighbour;            // kLanes per slot: the other end (the node itself in padding)
  std::vector<std::uint32_t> spring;               // kLanes per slot: the spring (0 in padding)
  AlignedDoubles real;                             // kLanes per slot: 1 for a spring, 0 for padding (zero block)

  bool matches(const SystemView& system) const {
    return system.node_count == nodes && system.spring_count == springs &&
           (springs == 0 || std::memcmp(ends.data(), system.springs, springs * sizeof(ends[0])) == 0);
  }

  void build(const SystemView& system) {
    nodes = system.node_count;
    springs = system.spring_count;
    padded = (nodes + kLanes - 1) / kLanes * kLanes;
    ends.assign(system.springs, system.springs + springs);
    auto owner = [&](std::size_t s) { return std::min(ends[s][0], ends[s][1]); };
    auto otherEnd = [&](std::size_t s) { return std::max(ends[s][0], ends[s][1]); };
    std::vector<std::uint32_t> start(padded + 1, 0);
    for (std::size_t s = 0; s < springs; ++s) ++start[owner(s) + 1];
    for (std::size_t k = 0; k < padded; ++k) start[k + 1] += start[k];
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    std::vector<std::uint32_t> owned(springs);
    for (std::size_t s = 0; s < springs; ++s) owned[fill[owner(s)]++] = static_cast<std::uint32_t>(s);
    for (std::size_t k = 0; k < nodes; ++k) {
      std::stable_sort(owned.begin() + start[k], owned.begin() + start[k + 1],
                       [&](std::uint32_t s, std::uint32_t t) { return otherEnd(s) < otherEnd(t); });
    }

    // A group's slots. By offset: one slot per offset (other end − node) that a lane's springs take, lanes without
    // it padded with the zero block at the node + offset, so the slot stays consecutive. By rank (where the offsets
    // are too many: an irregular patch): slot k holds each lane's k-th spring, gathered.
    const std::size_t groups = padded / kLanes;
    group_slots.assign(groups + 1, 0);
    neighbour.clear();
    spring.clear();
    real.clear();
    first_neighbour.clear();
    struct Slot {
      std::uint32_t offset;
      std::array<std::uint32_t, kLanes> spring;
      std::array<bool, kLanes> used;
    };
    std::vector<Slot> slots;
    for (std::size_t g = 0; g < groups; ++g) {
      const std::size_t base = g * kLanes;
      std::uint32_t width = 0;
      for (std::size_t k = base; k < base + kLanes; ++k) width = std::max(width, start[k + 1] - start[k]);
      slots.clear();
      for (std::size_t lane = 0; lane < kLanes; ++lane) {
        const std::size_t k = base + lane;
        for (std::uint32_t e = start[k]; e < start[k + 1]; ++e) {
          const std::uint32_t offset = otherEnd(owned[e]) - static_cast<std::uint32_t>(k);
          auto slot = std::find_if(slots.begin(), slots.end(),
                                   [&](const Slot& s) { return s.offset == offset && !s.used[lane]; });
          if (slot == slots.end()) slot = slots.insert(slots.end(), Slot{offset, {}, {}});
          slot->spring[lane] = owned[e];
          slot->used[lane] = true;
        }
      }
      const bool by_offset = slots.size() <= width + width / 2;
      if (by_offset) {
        std::stable_sort(slots.begin(), slots.end(), [](const Slot& s, const Slot& t) { return s.offset < t.offset; });
      } else {
        slots.assign(width, Slot{0, {}, {}});
        for (std::size_t lane = 0; lane < kLanes; ++lane) {
          const std::size_t k = base + lane;
          for (std::uint32_t e = start[k]; e < start[k + 1]; ++e) {
            slots[e - start[k]].spring[lane] = owned[e];
            slots[e - start[k]].used[lane] = true;
          }
        }
      }
      for (const Slot& slot : slots) {
        bool consecutive = true;
        const std::size_t first = neighbour.size();
        for (std::size_t lane = 0; lane < kLanes; ++lane) {
          const std::size_t k = base + lane;
          std::uint32_t other = static_cast<std::uint32_t>(k);  // padding: w = p_k − p_k = 0 with a zero block
          if (slot.used[lane]) {
            other = otherEnd(slot.spring[lane]);
          } else if (by_offset && k + slot.offset < padded) {
            other = static_cast<std::uint32_t>(k + slot.offset);  // zero block, other end in the slot's run
          }
          neighbour.push_back(other);
          spring.push_back(slot.used[lane] ? slot.spring[lane] : 0);
          real.push_back(slot.used[lane] ? 1.0 : 0.0);
          consecutive = consecutive && other == neighbour[first] + lane;
        }
        first_neighbour.push_back(consecutive ? static_cast<std::int32_t>(neighbour[first]) : -1);
      }
      group_slots[g + 1] = static_cast<std::uint32_t>(first_neighbour.size());
    }
    reach.assign(groups, 0);
    std::size_t furthest = 0;
    for (std::size_t g = 0; g < groups; ++g) {
      furthest = std::max(furthest, (g + 1) * kLanes);
      for (std::size_t k = kLanes * group_slots[g]; k < kLanes * group_slots[g + 1]; ++k) {
        furthest = std::max(furthest, (neighbour[k] / kLanes + 1) * kLanes);
      }
      reach[g] = static_cast<std::uint32_t>(furthest);
    }
  }
};

// Element-wise square root: each clone's widest vsqrtpd (the file is built with -fno-math-errno, like
// spring_kernels.cpp; with errno, std::sqrt keeps a branch that stops GCC from vectorising it). A 2-lane SSE2 form
// through memory it replaced spent most of the block pass on the spills.
inline Lanes squareRoot(const Lanes& x) {
  Lanes result;
  for (std::size_t lane = 0; lane < kLanes; ++lane) result[lane] = std::sqrt(x[lane]);
  return result;
}

// The other ends' values of a slot: one vector load where they are consecutive, else a gather.
inline Lanes otherEnds(const double* base, std::int32_t first, const std::uint32_t* neighbour) {
  return first >= 0 ? lanes(base + first) : gather(base, neighbour);
}

// Subtracts t from the other ends of a slot: one vector read-modify-write where they are consecutive, else lane by
// lane (two lanes of a gathered slot may share their other end).
inline void subtractAtOtherEnds(double* base, std::int32_t first, const std::uint32_t* neighbour, const Lanes& t) {
  if (first >= 0) {
    lanes(base + first) -= t;
  } else {
    for (std::size_t lane = 0; lane < kLanes; ++lane) base[neighbour[lane]] -= t[lane];
  }
}

// A spring's share t of a node vector ([x|y|z], stride n): added to its owners' sums (registers), subtracted at the
// other ends.
inline void addAtOwnerSubtractAtOtherEnds(Lanes& own_x, Lanes& own_y, Lanes& own_z, double* base, std::size_t n,
                                          std::int32_t first, const std::uint32_t* other, const Lanes& tx,
                                          const Lanes& ty, const Lanes& tz) {
  own_x += tx;
  own_y += ty;
  own_z += tz;
  subtractAtOtherEnds(base, first, other, tx);
  subtractAtOtherEnds(base + n, first, other, ty);
  subtractAtOtherEnds(base + 2 * n, first, other, tz);
}

// A Structure's arrays that the sweeps over the slots read.
struct SlotSweep {
  const std::uint32_t* group_slots;
  const std::int32_t* first_neighbour;
  const std::uint32_t* neighbour;
  const std::uint32_t* reach;
};

// What one sweep over the springs produces for a step ([x|y|z] vectors with stride n).
struct Assembly {
  double* blocks;                 // kBlockDoubles per slot: a, v_x, v_y, v_z of B_s = a·I + v vᵀ (scaled by Δt²)
  std::array<double*, 6> matrix;  // xx, yy, zz, xy, xz, yz of A's node blocks (xy, xz, yz only with off-diagonals)
  double* hooke;                  // Σ of the Hooke forces H_ij (eq. 5.2) on each node
  double* stiffness_velocity;     // Σ B_s (v_i − v_j) = Δt²·S_springs v⁰
};

// The step's one sweep over the springs at x⁰, v⁰: per spring its block B_s (eq. 5.8's Jacobian),
// added to both ends' node blocks; its Hooke force, as ForceModel computes it (k (|d| − l)/|d|·d, zero below the
// minimum length); and B_s (v_i − v_j) for the right-hand side. Each spring is read once, by the end with the lower
// index (see product()). Four sweeps before (the forces, the blocks, the node blocks, S v⁰) took 0.5 ms of
// a 1.3 ms step at 10k nodes. Returns Σ ½ k (|d| − l)², the springs' potential energy (ForceModel's capture).
template <bool kOffDiagonal>
__attribute__((always_inline)) inline double assembleSweep(std::size_t n, const SlotSweep& sweep,
                                                           const std::uint32_t* spring, const double* real,
                                                           const double* x, const double* v, const double* node_term,
                                                           const double* stiffnesses, const double* rest_lengths,
                                                           double scale, const Assembly& out) {
  const Lanes zero = {};
  const Lanes minimum = zero + kMinSpringLength;
  Lanes energy = zero;
  std::size_t initialised = 0;
  for (std::size_t g = 0; g < n / kLanes; ++g) {
    const std::size_t i = kLanes * g;
    // The outputs start at their initial values just ahead of the first write to them (see product()).
    for (; initialised < sweep.reach[g]; initialised += kLanes) {
      const std::size_t k = initialised;
      for (std::size_t c = 0; c < 3; ++c) {
        lanes(out.hooke + c * n + k) = zero;
        lanes(out.stiffness_velocity + c * n + k) = zero;
        lanes(out.matrix[c] + k) = lanes(node_term + k);
        if (kOffDiagonal) lanes(out.matrix[3 + c] + k) = zero;
      }
    }
    const Lanes xi = lanes(x + i), yi = lanes(x + n + i), zi = lanes(x + 2 * n + i);
    const Lanes vxi = lanes(v + i), vyi = lanes(v + n + i), vzi = lanes(v + 2 * n + i);
    Lanes fx = zero, fy = zero, fz = zero, sx = zero, sy = zero, sz = zero;
    Lanes xx = zero, yy = zero, zz = zero, xy = zero, xz = zero, yz = zero;
    for (std::uint32_t slot = sweep.group_slots[g]; slot < sweep.group_slots[g + 1]; ++slot) {
      const std::size_t at = kLanes * slot;
      const std::int32_t first = sweep.first_neighbour[slot];
      const std::uint32_t* other = sweep.neighbour + at;
      const Lanes dx = otherEnds(x, first, other) - xi;
      const Lanes dy = otherEnds(x + n, first, other) - yi;
      const Lanes dz = otherEnds(x + 2 * n, first, other) - zi;
      const Lanes k = lanes(real + at) * gather(stiffnesses, spring + at);
      const Lanes rest = gather(rest_lengths, spring + at);
      const Lanes length = squareRoot(dx * dx + dy * dy + dz * dz);
      const Lanes inverse_length = 1.0 / (length < minimum ? minimum : length);
      const Lanes elongation = length - rest;
      energy += 0.5 * k * elongation * elongation;
      const Lanes hooke = length < minimum ? zero : k * elongation * inverse_length;
      addAtOwnerSubtractAtOtherEnds(fx, fy, fz, out.hooke, n, first, other, hooke * dx, hooke * dy, hooke * dz);

      const Lanes scaled = length < minimum ? zero : scale * k;
      const Lanes stretch = 1.0 - rest * inverse_length;
      const Lanes transverse = stretch > zero ? stretch : zero;
      const Lanes a = scaled * transverse;
      const Lanes along = squareRoot(scaled * (1.0 - transverse)) * inverse_length;
      const Lanes bx = along * dx, by = along * dy, bz = along * dz;
      double* record = out.blocks + kBlockDoubles * slot;
      lanes(record) = a;
      lanes(record + kLanes) = bx;
      lanes(record + 2 * kLanes) = by;
      lanes(record + 3 * kLanes) = bz;

      const Lanes bxx = a + bx * bx, byy = a + by * by, bzz = a + bz * bz;
      const Lanes bxy = bx * by, bxz = bx * bz, byz = by * bz;
      xx += bxx;
      yy += byy;
      zz += bzz;
      xy += bxy;
      xz += bxz;
      yz += byz;
      subtractAtOtherEnds(out.matrix[0], first, other, -bxx);
      subtractAtOtherEnds(out.matrix[1], first, other, -byy);
      subtractAtOtherEnds(out.matrix[2], first, other, -bzz);
      if (kOffDiagonal) {
        subtractAtOtherEnds(out.matrix[3], first, other, -bxy);
        subtractAtOtherEnds(out.matrix[4], first, other, -bxz);
        subtractAtOtherEnds(out.matrix[5], first, other, -byz);
      }

      const Lanes wx = vxi - otherEnds(v, first, other);
      const Lanes wy = vyi - otherEnds(v + n, first, other);
      const Lanes wz = vzi - otherEnds(v + 2 * n, first, other);
      const Lanes projection = bx * wx + by * wy + bz * wz;
      addAtOwnerSubtractAtOtherEnds(sx, sy, sz, out.stiffness_velocity, n, first, other, a * wx + projection * bx,
                                    a * wy + projection * by, a * wz + projection * bz);
    }
    lanes(out.hooke + i) += fx;
    lanes(out.hooke + n + i) += fy;
    lanes(out.hooke + 2 * n + i) += fz;
    lanes(out.stiffness_velocity + i) += sx;
    lanes(out.stiffness_velocity + n + i) += sy;
    lanes(out.stiffness_velocity + 2 * n + i) += sz;
    lanes(out.matrix[0] + i) += xx;
    lanes(out.matrix[1] + i) += yy;
    lanes(out.matrix[2] + i) += zz;
    if (kOffDiagonal) {
      lanes(out.matrix[3] + i) += xy;
      lanes(out.matrix[4] + i) += xz;
      lanes(out.matrix[5] + i) += yz;
    }
  }
  return sum(energy);
}

// off_diagonal: whether the node blocks' xy, xz and yz are wanted (the block-Jacobi preconditioner); without, those
// three sums and their read-modify-writes are skipped (6 % of the step with Jacobi).
VRM_IMPLICIT_KERNEL
double assemble(std::size_t n, const SlotSweep& sweep, const std::uint32_t* spring, const double* real, const double* x,
                const double* v, const double* node_term, const double* stiffnesses, const double* rest_lengths,
                double scale, bool off_diagonal, const Assembly& out) {
  return off_diagonal
             ? assembleSweep<true>(n, sweep, spring, real, x, v, node_term, stiffnesses, rest_lengths, scale, out)
             : assembleSweep<false>(n, sweep, spring, real, x, v, node_term, stiffnesses, rest_lengths, scale, out);
}

// q = node_term·p + Σ_s B_s (p_i − p_j); returns p·q. Vectors are [x|y|z] with stride n (padded). Each spring's block
// is read once, by its owner: t = B_s (p_i − p_j) is added to the owner's sum in registers and subtracted from the
// other end in q, which has a higher index, so a group's q is complete when the sweep reaches its end. Read
// by both ends (a gather-only form), the blocks were streamed twice per product from beyond the 1 MB L2 of a core. The
// rows of constrained nodes are masked to zero.
VRM_IMPLICIT_KERNEL
double product(std::size_t n, const SlotSweep& sweep, const Springs& springs, const double* node_term, const double* p,
               double* q) {
  const double* px = p;
  const double* py = p + n;
  const double* pz = p + 2 * n;
  double* qx_out = q;
  double* qy_out = q + n;
  double* qz_out = q + 2 * n;
  const Lanes zero = {};
  std::size_t zeroed = 0;
  Lanes pq = zero;
  for (std::size_t g = 0; g < n / kLanes; ++g) {
    const std::size_t i = kLanes * g;
    // q is zeroed just ahead of the first subtraction from it, not in a pass of its own: the lines are then written
    // once while they are in L1 instead of being zeroed, evicted and fetched again (3·n doubles beyond L1 at 10k
    // nodes).
    for (; zeroed < sweep.reach[g]; zeroed += kLanes) {
      lanes(qx_out + zeroed) = zero;
      lanes(qy_out + zeroed) = zero;
      lanes(qz_out + zeroed) = zero;
    }
    const Lanes pix = lanes(px + i), piy = lanes(py + i), piz = lanes(pz + i);
    Lanes qx = zero, qy = zero, qz = zero;
    for (std::uint32_t slot = sweep.group_slots[g]; slot < sweep.group_slots[g + 1]; ++slot) {
      const std::int32_t first = sweep.first_neighbour[slot];
      const std::uint32_t* other = sweep.neighbour + kLanes * slot;
      const Lanes wx = pix - otherEnds(px, first, other);
      const Lanes wy = piy - otherEnds(py, first, other);
      const Lanes wz = piz - otherEnds(pz, first, other);
      Lanes vx, vy, vz, a;
      springs.load(slot, vx, vy, vz, a);
      const Lanes along = vx * wx + vy * wy + vz * wz;
      addAtOwnerSubtractAtOtherEnds(qx, qy, qz, q, n, first, other, a * wx + along * vx, a * wy + along * vy,
                                    a * wz + along * vz);
    }
    const Lanes term = lanes(node_term + i);
    const Lanes free = lanes(springs.mask + i);
    qx = free * (term * pix + qx + lanes(qx_out + i));
    qy = free * (term * piy + qy + lanes(qy_out + i));
    qz = free * (term * piz + qz + lanes(qz_out + i));
    lanes(qx_out + i) = qx;
    lanes(qy_out + i) = qy;
    lanes(qz_out + i) = qz;
    pq += pix * qx + piy * qy + piz * qz;
  }
  return sum(pq);
}

enum class Preconditioner { kNone, kJacobi, kBlockJacobi };

Preconditioner preconditionerNamed(const std::string& name) {
  if (name == "none") return Preconditioner::kNone;
  if (name == "jacobi") return Preconditioner::kJacobi;
  if (name == "block_jacobi") return Preconditioner::kBlockJacobi;
  throw std::invalid_argument("unknown CG preconditioner '" + name + "' (known: none, jacobi, block_jacobi)");
}

// The filtered preconditioner from the node blocks (in place): none → mask; Jacobi → mask / diagonal (dxx, dyy,
// dzz); block-Jacobi → mask · inverse of the symmetric 3×3 block (all six entries, by cofactors).
VRM_IMPLICIT_KERNEL
void invertNodeBlocks(std::size_t n, Preconditioner kind, const double* mask, double* dxx, double* dyy, double* dzz,
                      double* dxy, double* dxz, double* dyz) {
  // kLanes nodes at a time, every lane computed and the constrained ones and the padding (whose blocks may be
  // singular: padding has none) set to 0 afterwards; the same IEEE operations per node as one at a time.
  const Lanes zero = {};
  for (std::size_t i = 0; i < n; i += kLanes) {
    const Lanes free = lanes(mask + i);
    if (kind == Preconditioner::kNone) {
      lanes(dxx + i) = lanes(dyy + i) = lanes(dzz + i) = free;
    } else if (kind == Preconditioner::kJacobi) {
      lanes(dxx + i) = free == zero ? zero : 1.0 / lanes(dxx + i);
      lanes(dyy + i) = free == zero ? zero : 1.0 / lanes(dyy + i);
      lanes(dzz + i) = free == zero ? zero : 1.0 / lanes(dzz + i);
    } else {
      const Lanes a = lanes(dxx + i), b = lanes(dyy + i), c = lanes(dzz + i);
      const Lanes d = lanes(dxy + i), e = lanes(dxz + i), f = lanes(dyz + i);
      const Lanes cxx = b * c - f * f, cyy = a * c - e * e, czz = a * b - d * d;
      const Lanes cxy = e * f - d * c, cxz = d * f - b * e, cyz = d * e - a * f;
      const Lanes scale = 1.0 / (a * cxx + d * cxy + e * cxz);
      lanes(dxx + i) = free == zero ? zero : scale * cxx;
      lanes(dyy + i) = free == zero ? zero : scale * cyy;
      lanes(dzz + i) = free == zero ? zero : scale * czz;
      lanes(dxy + i) = free == zero ? zero : scale * cxy;
      lanes(dxz + i) = free == zero ? zero : scale * cxz;
      lanes(dyz + i) = free == zero ? zero : scale * cyz;
    }
  }
}

// The preconditioner's node blocks: xx, yy, zz (all kinds) and xy, xz, yz (block-Jacobi only).
struct NodeBlocks {
  const double* xx;
  const double* yy;
  const double* zz;
  const double* xy;
  const double* xz;
  const double* yz;
};

// r −= α·q, z = P·r over all nodes; returns (r·z, r·r). One pass, the preconditioner's kind fixed at compile time so
// the loop reads only the arrays it needs (the CG vector passes are bound by memory traffic like the product).
template <Preconditioner kKind>
__attribute__((always_inline)) inline std::pair<double, double> updateResidual(std::size_t n, double alpha,
                                                                               const NodeBlocks& inverse,
                                                                               const double* q, double* r, double* z) {
  Lanes rz_lanes = {};
  Lanes rr_lanes = rz_lanes;
  for (std::size_t i = 0; i < n; i += kLanes) {
    const Lanes rx = lanes(r + i) - alpha * lanes(q + i);
    const Lanes ry = lanes(r + n + i) - alpha * lanes(q + n + i);
    const Lanes rz = lanes(r + 2 * n + i) - alpha * lanes(q + 2 * n + i);
    lanes(r + i) = rx;
    lanes(r + n + i) = ry;
    lanes(r + 2 * n + i) = rz;
    Lanes zx, zy, zz;
    if (kKind == Preconditioner::kBlockJacobi) {
      const Lanes xy = lanes(inverse.xy + i), xz = lanes(inverse.xz + i), yz = lanes(inverse.yz + i);
      zx = lanes(inverse.xx + i) * rx + xy * ry + xz * rz;
      zy = xy * rx + lanes(inverse.yy + i) * ry + yz * rz;
      zz = xz * rx + yz * ry + lanes(inverse.zz + i) * rz;
    } else if (kKind == Preconditioner::kJacobi) {
      zx = lanes(inverse.xx + i) * rx;
      zy = lanes(inverse.yy + i) * ry;
      zz = lanes(inverse.zz + i) * rz;
    } else {  // the mask (in xx): the filter of the unpreconditioned CG
      const Lanes free = lanes(inverse.xx + i);
      zx = free * rx;
      zy = free * ry;
      zz = free * rz;
    }
    lanes(z + i) = zx;
    lanes(z + n + i) = zy;
    lanes(z + 2 * n + i) = zz;
    rz_lanes += rx * zx + ry * zy + rz * zz;
    rr_lanes += rx * rx + ry * ry + rz * rz;
  }
  return {sum(rz_lanes), sum(rr_lanes)};
}

struct SolveResult {
  int iterations = 0;
  double residual = 0.0;  // |r| / |b|
};

// Filtered preconditioned CG. On entry r = b − A·Δv₀ (filtered), dv = Δv₀, b_norm2 = |b|². Vectors [x|y|z], stride n.
// Per iteration: the product (p → q, p·q), one pass for r and z = P·r with both dot products, one pass for Δv and p.
template <Preconditioner kKind>
__attribute__((always_inline)) inline SolveResult conjugateGradients(std::size_t n, const SlotSweep& sweep,
                                                                     const Springs& blocks, const double* node_term,
                                                                     const NodeBlocks& inverse, double b_norm2,
                                                                     double* r, double* z, double* p, double* q,
                                                                     double* dv, int max_iterations, double tolerance) {
  auto [rz, r_norm2] = updateResidual<kKind>(n, 0.0, inverse, q, r, z);
  std::memcpy(p, z, 3 * n * sizeof(double));
  const double tolerance2 = tolerance * tolerance * b_norm2;
  SolveResult result;
  // NaN in b or A fails every comparison below, so a poisoned system ends the loop instead of spinning.
  while (result.iterations < max_iterations && r_norm2 > tolerance2 && b_norm2 > 0.0) {
    const double pq = product(n, sweep, blocks, node_term, p, q);
    if (!(pq > 0.0)) break;
    const double alpha = rz / pq;
    const auto [rz_new, rr_new] = updateResidual<kKind>(n, alpha, inverse, q, r, z);
    r_norm2 = rr_new;
    const double beta = rz_new / rz;
    rz = rz_new;
    for (std::size_t k = 0; k < 3 * n; k += kLanes) {
      const Lanes pk = lanes(p + k);
      lanes(dv + k) += alpha * pk;
      lanes(p + k) = lanes(z + k) + beta * pk;
    }
    ++result.iterations;
  }
  // 0 for b = 0 (Δv = 0 is exact); NaN when b is NaN, so callers see that the solve did not run.
  result.residual = b_norm2 > 0.0 ? std::sqrt(r_norm2 / b_norm2) : (b_norm2 == 0.0 ? 0.0 : b_norm2);
  return result;
}

VRM_IMPLICIT_KERNEL
SolveResult solve(Preconditioner kind, std::size_t n, const SlotSweep& sweep, const Springs& blocks,
                  const double* node_term, const NodeBlocks& inverse, double b_norm2, double* r, double* z, double* p,
                  double* q, double* dv, int max_iterations, double tolerance) {
  // q = 0 so that the first updateResidual (α = 0) only computes z = P·r.
  std::fill(q, q + 3 * n, 0.0);
  switch (kind) {
    case Preconditioner::kNone:
      return conjugateGradients<Preconditioner::kNone>(n, sweep, blocks, node_term, inverse, b_norm2, r, z, p, q, dv,
                                                       max_iterations, tolerance);
    case Preconditioner::kJacobi:
      return conjugateGradients<Preconditioner::kJacobi>(n, sweep, blocks, node_term, inverse, b_norm2, r, z, p, q, dv,
                                                         max_iterations, tolerance);
    case Preconditioner::kBlockJacobi:
      break;
  }
  return conjugateGradients<Preconditioner::kBlockJacobi>(n, sweep, blocks, node_term, inverse, b_norm2, r, z, p, q, dv,
                                                          max_iterations, tolerance);
}

// The node terms as structure of arrays: node_term = m + Δt·c + anchor_term, the filter mask (1 free, 0 constrained),
// v⁰ and x⁰ ([x|y|z], stride n). Nodes beyond `count` (padding) are left as they are: constrained zeros.
VRM_IMPLICIT_KERNEL
void loadNodes(const SystemView& system, std::size_t n, double damping, const double* anchor_term, double* node_term,
               double* mask, double* v0, double* x0) {
  const std::size_t count = system.node_count;
  for (std::size_t k = 0; k < count; ++k) {
    node_term[k] = system.masses[k] + damping + anchor_term[k];
    mask[k] = system.isFree(k) ? 1.0 : 0.0;
  }
  for (std::size_t c = 0; c < 3; ++c) {
    for (std::size_t k = 0; k < count; ++k) {
      v0[c * n + k] = system.velocities[k][c];
      x0[c * n + k] = system.positions[k][c];
    }
  }
}

// r = b = mask·(Δt·(F⁰ + Hooke) − (Δt²·k_anchor·v⁰ + Δt²·S_springs v⁰)); returns |b|², summed per lane (k mod kLanes)
// and then over the lanes, like the CG's dot products. A sum in node order was one chain of 3·count dependent adds.
VRM_IMPLICIT_KERNEL
double rightHandSide(std::size_t count, std::size_t n, double h, const Eigen::Vector3d* forces, const double* hooke,
                     const double* anchor_term, const double* v0, const double* stiffness_velocity, const double* mask,
                     double* r) {
  Lanes squares = {};
  for (std::size_t c = 0; c < 3; ++c) {
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t index = c * n + k;
      r[index] =
          mask[k] * (h * (forces[k][c] + hooke[index]) - (anchor_term[k] * v0[index] + stiffness_velocity[index]));
    }
  }
  const std::size_t full = count / kLanes * kLanes;
  for (std::size_t k = 0; k < full; k += kLanes) {
    const Lanes rx = lanes(r + k), ry = lanes(r + n + k), rz = lanes(r + 2 * n + k);
    squares += rx * rx + ry * ry + rz * rz;
  }
  for (std::size_t k = full; k < count; ++k) {
    squares[k - full] += r[k] * r[k] + r[n + k] * r[n + k] + r[2 * n + k] * r[2 * n + k];
  }
  return sum(squares);
}

class ImplicitEuler : public Integrator {
 public:
  explicit ImplicitEuler(const IntegratorOptions& options)
      : options_(options), preconditioner_(preconditionerNamed(options.cg_preconditioner)) {}
  const char* name() const override { return "implicit_euler"; }
  int lastIterations() const override { return iterations_; }
  double lastResidual() const override { return residual_; }

  // The warm start: the last solve's Δv and dt, if the next step will find the structure it was built for (no
  // topology change since); else nothing, and both the original and the restored solver start cold.
  void transferState(StateArchive& archive, const SystemView& system) override {
    bool warm = archive.saving() && previous_dt_ > 0.0 && structure_.matches(system);
    archive(warm);
    if (!warm) {
      if (archive.loading()) previous_dt_ = 0.0;
      return;
    }
    if (archive.loading()) resize(system);
    const std::size_t expected = dv_.size();
    archive(previous_dt_)(dv_);
    if (archive.loading() && dv_.size() != expected)
      archive.fail("the implicit warm start is for another membrane size");
  }

  void step(const SystemView& system, const ForceModel& forces, double dt) override {
    const bool topology_changed = !structure_.matches(system);
    if (topology_changed) resize(system);
    const std::size_t n = structure_.padded;
    const double h = dt;
    const double h2 = dt * dt;

    // Everything but the Hooke terms here; those come from the assembly sweep below, which also takes over the
    // watchdog's capture of the spring energy.
    double* const spring_energy = forces.takeSpringEnergyCapture();
    forces.computeExceptSprings(system, system.positions, system.velocities, forces_.data());
    // Node terms as structure of arrays: anchor_term = Δt²·k_anchor (its part of Δt²·S), node_term = m + Δt·c +
    // anchor_term; the padding lanes beyond node_count stay constrained zeros.
    double* anchor_term = anchor_term_.data();
    double* node_term = node_term_.data();
    double* mask = mask_.data();
    double* v0 = p_.data();
    double* x0 = positions_.data();
    std::fill(anchor_term, anchor_term + n, 0.0);
    for (const Anchor& anchor : forces.anchors) anchor_term[anchor.node] += h2 * anchor.stiffness;
    loadNodes(system, n, h * forces.params.damping, anchor_term, node_term, mask, v0, x0);

    const SlotSweep sweep{structure_.group_slots.data(), structure_.first_neighbour.data(), structure_.neighbour.data(),
                          structure_.reach.data()};
    double* q = q_.data();
    double* r = r_.data();
    double* hooke = z_.data();  // z is free until the solve
    const Assembly assembly{spring_blocks_.data(),
                            {node_blocks_[0].data(), node_blocks_[1].data(), node_blocks_[2].data(),
                             node_blocks_[3].data(), node_blocks_[4].data(), node_blocks_[5].data()},
                            hooke,
                            q};
    const double energy =
        assemble(n, sweep, structure_.spring.data(), structure_.real.data(), x0, v0, node_term, system.stiffnesses,
                 system.rest_lengths, h2, preconditioner_ == Preconditioner::kBlockJacobi, assembly);
    if (spring_energy != nullptr) *spring_energy = energy;
    const Springs springs{spring_blocks_.data(), mask};
    invertNodeBlocks(n, preconditioner_, mask, node_blocks_[0].data(), node_blocks_[1].data(), node_blocks_[2].data(),
                     node_blocks_[3].data(), node_blocks_[4].data(), node_blocks_[5].data());

    // b = mask·(Δt·F⁰ − Δt²·S v⁰), S v⁰ = the springs' part (q, from the sweep) + the anchors'.
    const double b_norm2 = rightHandSide(system.node_count, n, h, forces_.data(), hooke, anchor_term, v0, q, mask, r);

    // Warm start: the last Δv, scaled by dt / previous dt (Δv ≈ Δt·acceleration), r = b − A·Δv₀.
    double* dv = dv_.data();
    const bool warm = options_.cg_warm_start && !topology_changed && previous_dt_ > 0.0;
    if (warm) {
      const double scale = dt / previous_dt_;
      for (int c = 0; c < 3; ++c) {
        for (std::size_t k = 0; k < n; ++k) dv[c * n + k] *= scale * mask[k];
      }
      product(n, sweep, springs, node_term, dv, q);
      for (std::size_t k = 0; k < 3 * n; ++k) r[k] -= q[k];
    } else {
      std::fill(dv, dv + 3 * n, 0.0);
    }

    const NodeBlocks inverse{node_blocks_[0].data(), node_blocks_[1].data(), node_blocks_[2].data(),
                             node_blocks_[3].data(), node_blocks_[4].data(), node_blocks_[5].data()};
    const SolveResult result = solve(preconditioner_, n, sweep, springs, node_term, inverse, b_norm2, r, z_.data(),
                                     p_.data(), q, dv, options_.cg_max_iterations, options_.cg_tolerance);
    iterations_ = result.iterations;
    residual_ = result.residual;
    previous_dt_ = dt;

    for (std::size_t k = 0; k < system.node_count; ++k) {
      if (mask[k] == 0.0) continue;
      Eigen::Vector3d& v = system.velocities[k];
      v += Eigen::Vector3d(dv[k], dv[n + k], dv[2 * n + k]);
      system.positions[k] += h * v;
    }
  }

 private:
  void resize(const SystemView& system) {
    structure_.build(system);
    const std::size_t n = structure_.padded;
    forces_.assign(system.node_count, Eigen::Vector3d::Zero());
    for (auto* vector : {&r_, &z_, &p_, &q_, &dv_, &positions_}) vector->assign(3 * n, 0.0);
    for (auto* vector : {&anchor_term_, &node_term_, &mask_}) vector->assign(n, 0.0);
    for (auto& block : node_blocks_) block.assign(n, 0.0);
    spring_blocks_.assign(4 * structure_.spring.size(), 0.0);
    previous_dt_ = 0.0;
  }

  IntegratorOptions options_;
  Preconditioner preconditioner_;
  int iterations_ = 0;
  double residual_ = 0.0;
  double previous_dt_ = 0.0;  // of the last solve (warm start); 0 after a topology change
  Structure structure_;
  std::vector<Eigen::Vector3d> forces_;
  AlignedDoubles r_, z_, p_, q_, dv_;  // [x|y|z], stride structure_.padded
  AlignedDoubles positions_;           // x⁰, [x|y|z] like the CG vectors
  AlignedDoubles anchor_term_, node_term_, mask_;
  std::array<AlignedDoubles, 6> node_blocks_;  // xx, yy, zz, xy, xz, yz of A, then of the preconditioner
  // One record per slot (Springs, Assembly::blocks).
  AlignedDoubles spring_blocks_;
};

}  // namespace

std::unique_ptr<Integrator> makeImplicitEuler(const IntegratorOptions& options) {
  return std::make_unique<ImplicitEuler>(options);
}

}  // namespace tissue
}  // namespace vrm_sim
