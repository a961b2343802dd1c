#include <Eigen/Core>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
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
// Layout, chosen for the product A·p that every CG iteration runs once (issue 15):
//  - node vectors are structure of arrays [x…|y…|z…] in an internal node order (Structure), padded to kLanes;
//  - the product gathers instead of scattering: nodes are taken kLanes at a time (one SIMD lane each) and their
//    springs slot by slot (sliced ELLPACK: slot k holds the k-th spring of each node of the group, padded with the
//    zero block to the group's largest degree). A sweep loads the neighbours and the blocks (one vector load per
//    array where the lanes' indices are consecutive, else a gather) and writes each q_i once — no read-modify-write
//    chains, no horizontal sums;
//  - each spring's block (a, v) is stored once, in an internal spring order that makes both of its slots read
//    consecutive ids in a regular patch.
// Measured (bench_implicit, 10k nodes, one run, median ms per step with 10 CG iterations): the packed-record scatter
// form this replaced 3.00 ms at dt 1 ms, this one 1.93. The step is bound by memory traffic, not arithmetic: AVX-512
// with 8 lanes ran as fast as AVX2 with 4; a slot-record layout (each block stored twice, 2 MB at 10k nodes, which
// with the CG vectors overflows the 2 MB L2) spent ~28 % of the step on reading the records. Profile now: product
// 35 %, CG vector passes 20 %, springBlocks 16 %, ForceModel::compute 7 %. Tried and not kept: float blocks (5 %
// faster, but CG then converges to the rounded matrix, ~1e-7 relative, and the dense-solve tests ask for 1e-9).
// Constrained nodes (pinned or grasped) are handled by the filtered CG of Baraff & Witkin §5.3: their rows of A are
// zero blocks and their preconditioner is zero, so p, Δv and r stay zero on them — the "infinite mass" of the thesis
// without ill-conditioning. A step allocates nothing once the buffers have their size.

// Built for AVX-512, AVX2+FMA and the baseline, picked at load time like spring_kernels.cpp. The builds round
// differently (FMA, lane order of the dot products); the implicit solve is iterative and not part of any bit-exact
// contract, but each build is deterministic.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define VRM_IMPLICIT_KERNEL __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define VRM_IMPLICIT_KERNEL
#endif

constexpr std::size_t kLanes = 8;
// kLanes doubles (one AVX-512 register, two AVX2 ones); unaligned loads and stores through this type alias double.
typedef double Lanes __attribute__((vector_size(8 * kLanes), aligned(8), may_alias));

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

// The blocks B_s = a·I + v vᵀ of the springs in internal spring order (plus one zero block for padding) and, per slot,
// which springs its lanes hold: consecutive ids (one vector load per array) where the structure allows, else a gather.
struct Springs {
  const double* a;
  const double* vx;
  const double* vy;
  const double* vz;
  const std::int32_t* first;  // per slot: id of lane 0's spring when the lanes hold consecutive ids, else −1
  const std::uint32_t* ids;   // kLanes per slot
  const double* mask;         // per node: 1 free, 0 constrained (rows of A·p that are filtered out)

  void load(std::uint32_t slot, Lanes& bx, Lanes& by, Lanes& bz, Lanes& ba) const {
    const std::int32_t id = first[slot];
    if (id >= 0) {
      bx = lanes(vx + id);
      by = lanes(vy + id);
      bz = lanes(vz + id);
      ba = lanes(a + id);
    } else {
      const std::uint32_t* lane_ids = ids + kLanes * slot;
      bx = gather(vx, lane_ids);
      by = gather(vy, lane_ids);
      bz = gather(vz, lane_ids);
      ba = gather(a, lane_ids);
    }
  }
};

// The node-ordered spring structure; depends on the topology only. Nodes are renumbered internally (order[k] = the
// node in internal slot k): by degree, then by index. Same-degree nodes then share groups (little ELLPACK padding:
// the grid membrane alternates degree 8 and 4 along its rows), and each node's springs are sorted by the index offset
// of their other end, so in a regular patch slot k of a group points the same way for all 4 lanes and its 4
// neighbours are 4 consecutive internal nodes — one vector load per component instead of a 4-way gather.
struct Structure {
  std::size_t nodes = 0, padded = 0, springs = 0;
  std::vector<std::array<std::uint32_t, 2>> ends;  // copy of the spring ends it was built from
  std::vector<std::uint32_t> order;                // internal → node (padded: order[k] = nodes for k ≥ nodes)
  std::vector<std::uint32_t> internal;             // node → internal
  std::vector<std::uint32_t> group_slots;          // first slot of group g; group_slots[groups] = slot count
  std::vector<std::int32_t> first_neighbour;       // per slot: internal neighbour of lane 0 if the 4 are consecutive
  std::vector<std::uint32_t> neighbour;            // 4 per slot: internal other end (the node itself in padding)
  std::vector<std::uint32_t> spring;               // kLanes per slot: internal spring id (springs: the zero block)
  std::vector<std::int32_t> first_spring;          // per slot: id of lane 0 if the lanes' ids are consecutive
  std::vector<std::uint32_t> spring_order;         // internal spring id → spring

  bool matches(const SystemView& system) const {
    return system.node_count == nodes && system.spring_count == springs &&
           (springs == 0 || std::memcmp(ends.data(), system.springs, springs * sizeof(ends[0])) == 0);
  }

  void build(const SystemView& system) {
    nodes = system.node_count;
    springs = system.spring_count;
    padded = (nodes + kLanes - 1) / kLanes * kLanes;
    ends.assign(system.springs, system.springs + springs);
    std::vector<std::uint32_t> degree(nodes, 0);
    for (const auto& e : ends) {
      ++degree[e[0]];
      ++degree[e[1]];
    }
    std::vector<std::uint32_t> start(nodes + 1, 0);
    for (std::size_t i = 0; i < nodes; ++i) start[i + 1] = start[i] + degree[i];
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    std::vector<std::uint32_t> adjacent_spring(2 * springs);
    for (std::size_t s = 0; s < springs; ++s) {
      adjacent_spring[fill[ends[s][0]]++] = static_cast<std::uint32_t>(s);
      adjacent_spring[fill[ends[s][1]]++] = static_cast<std::uint32_t>(s);
    }
    auto other = [this](std::uint32_t s, std::size_t i) { return ends[s][0] == i ? ends[s][1] : ends[s][0]; };
    for (std::size_t i = 0; i < nodes; ++i) {
      std::sort(adjacent_spring.begin() + start[i], adjacent_spring.begin() + start[i + 1],
                [&](std::uint32_t s, std::uint32_t t) { return other(s, i) < other(t, i); });
    }
    order.resize(padded);
    for (std::size_t k = 0; k < padded; ++k) order[k] = static_cast<std::uint32_t>(std::min(k, nodes));
    std::stable_sort(order.begin(), order.begin() + nodes,
                     [&](std::uint32_t i, std::uint32_t j) { return degree[i] > degree[j]; });
    internal.assign(nodes, 0);
    for (std::size_t k = 0; k < nodes; ++k) internal[order[k]] = static_cast<std::uint32_t>(k);

    const std::size_t groups = padded / kLanes;
    auto degreeAt = [&](std::size_t k) { return k < nodes ? degree[order[k]] : 0u; };
    group_slots.assign(groups + 1, 0);
    for (std::size_t g = 0; g < groups; ++g) {
      std::uint32_t width = 0;
      for (std::size_t lane = 0; lane < kLanes; ++lane) width = std::max(width, degreeAt(g * kLanes + lane));
      group_slots[g + 1] = group_slots[g] + width;
    }
    const std::size_t slots = group_slots[groups];
    neighbour.assign(kLanes * slots, 0);
    spring.assign(kLanes * slots, static_cast<std::uint32_t>(springs));
    first_neighbour.assign(slots, -1);
    for (std::size_t g = 0; g < groups; ++g) {
      for (std::uint32_t slot = group_slots[g]; slot < group_slots[g + 1]; ++slot) {
        const std::uint32_t k = slot - group_slots[g];
        bool consecutive = true;
        for (std::size_t lane = 0; lane < kLanes; ++lane) {
          const std::size_t node_internal = g * kLanes + lane;
          const std::size_t e = kLanes * slot + lane;
          if (k < degreeAt(node_internal)) {
            const std::size_t i = order[node_internal];
            const std::uint32_t s = adjacent_spring[start[i] + k];
            spring[e] = s;
            neighbour[e] = internal[other(s, i)];
          } else {
            neighbour[e] = static_cast<std::uint32_t>(node_internal);  // w = p_i − p_i = 0 with a zero block
          }
          consecutive = consecutive && neighbour[e] == neighbour[kLanes * slot] + lane;
        }
        if (consecutive) first_neighbour[slot] = static_cast<std::int32_t>(neighbour[kLanes * slot]);
      }
    }
    // Internal spring ids, handed out slot index by slot index over all groups: in a regular patch the two ends of a
    // run of springs are runs of nodes in two groups' slots with the same direction, so both ends see consecutive
    // ids and every spring block is stored once.
    const std::uint32_t unassigned = std::numeric_limits<std::uint32_t>::max();
    std::vector<std::uint32_t> id_of(springs + 1, unassigned);
    id_of[springs] = static_cast<std::uint32_t>(springs);
    spring_order.clear();
    std::uint32_t widest = 0;
    for (std::size_t g = 0; g < groups; ++g) widest = std::max(widest, group_slots[g + 1] - group_slots[g]);
    for (std::uint32_t k = 0; k < widest; ++k) {
      for (std::size_t g = 0; g < groups; ++g) {
        if (k >= group_slots[g + 1] - group_slots[g]) continue;
        for (std::size_t lane = 0; lane < kLanes; ++lane) {
          const std::uint32_t s = spring[kLanes * (group_slots[g] + k) + lane];
          if (id_of[s] != unassigned) continue;
          id_of[s] = static_cast<std::uint32_t>(spring_order.size());
          spring_order.push_back(s);
        }
      }
    }
    first_spring.assign(slots, -1);
    for (std::size_t slot = 0; slot < slots; ++slot) {
      bool consecutive = true;
      for (std::size_t lane = 0; lane < kLanes; ++lane) {
        std::uint32_t& s = spring[kLanes * slot + lane];
        s = id_of[s];
        consecutive = consecutive && s < springs && s == spring[kLanes * slot] + lane;
      }
      if (consecutive) first_spring[slot] = static_cast<std::int32_t>(spring[kLanes * slot]);
    }
  }
};

// Element-wise square root. std::sqrt keeps an errno branch (-fmath-errno is on), which stops GCC from vectorising
// any loop that calls it; SSE2's sqrtpd exists in every clone and rounds exactly like std::sqrt.
inline Lanes squareRoot(const Lanes& x) {
#if defined(__SSE2__)
  double values[kLanes];
  std::memcpy(values, &x, sizeof(values));
  for (std::size_t lane = 0; lane < kLanes; lane += 2) {
    _mm_storeu_pd(values + lane, _mm_sqrt_pd(_mm_loadu_pd(values + lane)));
  }
  Lanes result;
  std::memcpy(&result, values, sizeof(values));
  return result;
#else
  Lanes result;
  for (std::size_t lane = 0; lane < kLanes; ++lane) result[lane] = std::sqrt(x[lane]);
  return result;
#endif
}

// Per spring, in internal order: a_s and v_s of B_s = a_s·I + v_s v_sᵀ for the current positions (id `springs`
// stays zero: padding). stiffnesses and rest_lengths are scratch arrays for the reordered inputs.
// Two loops, like kernels::hookeForces: the gather is scalar, the two square roots and the division per spring then
// run kLanes springs at a time (scalar they were 10 % of the step).
VRM_IMPLICIT_KERNEL
void springBlocks(std::size_t m, const std::uint32_t* spring_order, const std::array<std::uint32_t, 2>* ends,
                  const Eigen::Vector3d* x, const double* spring_stiffnesses, const double* spring_rest_lengths,
                  double scale, double* stiffnesses, double* rest_lengths, double* a, double* vx, double* vy,
                  double* vz) {
  for (std::size_t s = 0; s < m; ++s) {
    const std::uint32_t spring = spring_order[s];
    const Eigen::Vector3d& xa = x[ends[spring][0]];
    const Eigen::Vector3d& xb = x[ends[spring][1]];
    vx[s] = xb.x() - xa.x();
    vy[s] = xb.y() - xa.y();
    vz[s] = xb.z() - xa.z();
    stiffnesses[s] = spring_stiffnesses[spring];
    rest_lengths[s] = spring_rest_lengths[spring];
  }
  const Lanes zero = {};
  const Lanes minimum = zero + kMinSpringLength;
  std::size_t s = 0;
  for (; s + kLanes <= m; s += kLanes) {
    const Lanes dx = lanes(vx + s), dy = lanes(vy + s), dz = lanes(vz + s);
    const Lanes length = squareRoot(dx * dx + dy * dy + dz * dz);
    const Lanes inverse_length = 1.0 / (length < minimum ? minimum : length);
    const Lanes k = length < minimum ? zero : scale * lanes(stiffnesses + s);
    const Lanes stretch = 1.0 - lanes(rest_lengths + s) * inverse_length;
    const Lanes transverse = stretch > zero ? stretch : zero;
    lanes(a + s) = k * transverse;
    const Lanes along = squareRoot(k * (1.0 - transverse)) * inverse_length;
    lanes(vx + s) = along * dx;
    lanes(vy + s) = along * dy;
    lanes(vz + s) = along * dz;
  }
  for (; s < m; ++s) {
    const double dx = vx[s], dy = vy[s], dz = vz[s];
    const double length = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double inverse_length = 1.0 / std::max(length, kMinSpringLength);
    const double k = length < kMinSpringLength ? 0.0 : scale * stiffnesses[s];
    const double transverse = std::max(0.0, 1.0 - rest_lengths[s] * inverse_length);
    a[s] = k * transverse;
    const double along = std::sqrt(k * (1.0 - transverse)) * inverse_length;
    vx[s] = along * dx;
    vy[s] = along * dy;
    vz[s] = along * dz;
  }
}

// Adds the spring blocks to the 3×3 node blocks of A (diagonal dxx, dyy, dzz and off-diagonal dxy, dxz, dyz; these
// hold the node term m + Δt·c + Δt²·k_anchor on entry).
VRM_IMPLICIT_KERNEL
void nodeBlocks(std::size_t groups, const std::uint32_t* group_slots, const Springs& springs, double* dxx, double* dyy,
                double* dzz, double* dxy, double* dxz, double* dyz) {
  for (std::size_t g = 0; g < groups; ++g) {
    const std::size_t i = kLanes * g;
    Lanes xx = lanes(dxx + i), yy = lanes(dyy + i), zz = lanes(dzz + i);
    Lanes xy = lanes(dxy + i), xz = lanes(dxz + i), yz = lanes(dyz + i);
    for (std::uint32_t slot = group_slots[g]; slot < group_slots[g + 1]; ++slot) {
      Lanes bx, by, bz, ba;
      springs.load(slot, bx, by, bz, ba);
      xx += ba + bx * bx;
      yy += ba + by * by;
      zz += ba + bz * bz;
      xy += bx * by;
      xz += bx * bz;
      yz += by * bz;
    }
    lanes(dxx + i) = xx;
    lanes(dyy + i) = yy;
    lanes(dzz + i) = zz;
    lanes(dxy + i) = xy;
    lanes(dxz + i) = xz;
    lanes(dyz + i) = yz;
  }
}

// q = node_term·p + Σ_s B_s (p_i − p_j) over node-ordered slots; returns p·q. Vectors are [x|y|z] with stride n
// (padded). The rows of constrained nodes are masked to zero.
VRM_IMPLICIT_KERNEL
double product(std::size_t n, const std::uint32_t* group_slots, const std::int32_t* first_neighbour,
               const std::uint32_t* neighbour, const Springs& springs, const double* node_term, const double* p,
               double* q) {
  const double* px = p;
  const double* py = p + n;
  const double* pz = p + 2 * n;
  Lanes pq = {};
  for (std::size_t g = 0; g < n / kLanes; ++g) {
    const std::size_t i = kLanes * g;
    const Lanes pix = lanes(px + i), piy = lanes(py + i), piz = lanes(pz + i);
    const Lanes term = lanes(node_term + i);
    Lanes qx = term * pix, qy = term * piy, qz = term * piz;
    for (std::uint32_t slot = group_slots[g]; slot < group_slots[g + 1]; ++slot) {
      Lanes wx, wy, wz;
      const std::int32_t first = first_neighbour[slot];
      if (first >= 0) {
        wx = pix - lanes(px + first);
        wy = piy - lanes(py + first);
        wz = piz - lanes(pz + first);
      } else {
        const std::uint32_t* j = neighbour + kLanes * slot;
        wx = pix - gather(px, j);
        wy = piy - gather(py, j);
        wz = piz - gather(pz, j);
      }
      Lanes vx, vy, vz, a;
      springs.load(slot, vx, vy, vz, a);
      const Lanes along = vx * wx + vy * wy + vz * wz;
      qx += a * wx + along * vx;
      qy += a * wy + along * vy;
      qz += a * wz + along * vz;
    }
    const Lanes free = lanes(springs.mask + i);
    qx *= free;
    qy *= free;
    qz *= free;
    lanes(q + i) = qx;
    lanes(q + n + i) = qy;
    lanes(q + 2 * n + i) = qz;
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
  for (std::size_t i = 0; i < n; ++i) {
    // The padding lanes and constrained nodes get 0 (their blocks may be singular: padding has none).
    const double free = mask[i];
    if (free == 0.0) {
      dxx[i] = dyy[i] = dzz[i] = dxy[i] = dxz[i] = dyz[i] = 0.0;
    } else if (kind == Preconditioner::kNone) {
      dxx[i] = dyy[i] = dzz[i] = 1.0;
      dxy[i] = dxz[i] = dyz[i] = 0.0;
    } else if (kind == Preconditioner::kJacobi) {
      dxx[i] = 1.0 / dxx[i];
      dyy[i] = 1.0 / dyy[i];
      dzz[i] = 1.0 / dzz[i];
      dxy[i] = dxz[i] = dyz[i] = 0.0;
    } else {
      const double a = dxx[i], b = dyy[i], c = dzz[i], d = dxy[i], e = dxz[i], f = dyz[i];
      const double cxx = b * c - f * f, cyy = a * c - e * e, czz = a * b - d * d;
      const double cxy = e * f - d * c, cxz = d * f - b * e, cyz = d * e - a * f;
      const double scale = 1.0 / (a * cxx + d * cxy + e * cxz);
      dxx[i] = scale * cxx;
      dyy[i] = scale * cyy;
      dzz[i] = scale * czz;
      dxy[i] = scale * cxy;
      dxz[i] = scale * cxz;
      dyz[i] = scale * cyz;
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
__attribute__((always_inline)) inline SolveResult conjugateGradients(
    std::size_t n, const std::uint32_t* group_slots, const std::int32_t* first_neighbour,
    const std::uint32_t* neighbour, const Springs& blocks, const double* node_term, const NodeBlocks& inverse,
    double b_norm2, double* r, double* z, double* p, double* q, double* dv, int max_iterations, double tolerance) {
  auto [rz, r_norm2] = updateResidual<kKind>(n, 0.0, inverse, q, r, z);
  std::memcpy(p, z, 3 * n * sizeof(double));
  const double tolerance2 = tolerance * tolerance * b_norm2;
  SolveResult result;
  // NaN in b or A fails every comparison below, so a poisoned system ends the loop instead of spinning.
  while (result.iterations < max_iterations && r_norm2 > tolerance2 && b_norm2 > 0.0) {
    const double pq = product(n, group_slots, first_neighbour, neighbour, blocks, node_term, p, q);
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
SolveResult solve(Preconditioner kind, std::size_t n, const std::uint32_t* group_slots,
                  const std::int32_t* first_neighbour, const std::uint32_t* neighbour, const Springs& blocks,
                  const double* node_term, const NodeBlocks& inverse, double b_norm2, double* r, double* z, double* p,
                  double* q, double* dv, int max_iterations, double tolerance) {
  // q = 0 so that the first updateResidual (α = 0) only computes z = P·r.
  std::fill(q, q + 3 * n, 0.0);
  switch (kind) {
    case Preconditioner::kNone:
      return conjugateGradients<Preconditioner::kNone>(n, group_slots, first_neighbour, neighbour, blocks, node_term,
                                                       inverse, b_norm2, r, z, p, q, dv, max_iterations, tolerance);
    case Preconditioner::kJacobi:
      return conjugateGradients<Preconditioner::kJacobi>(n, group_slots, first_neighbour, neighbour, blocks, node_term,
                                                         inverse, b_norm2, r, z, p, q, dv, max_iterations, tolerance);
    case Preconditioner::kBlockJacobi:
      break;
  }
  return conjugateGradients<Preconditioner::kBlockJacobi>(n, group_slots, first_neighbour, neighbour, blocks, node_term,
                                                          inverse, b_norm2, r, z, p, q, dv, max_iterations, tolerance);
}

class ImplicitEuler : public Integrator {
 public:
  explicit ImplicitEuler(const IntegratorOptions& options)
      : options_(options), preconditioner_(preconditionerNamed(options.cg_preconditioner)) {}
  const char* name() const override { return "implicit_euler"; }
  int lastIterations() const override { return iterations_; }
  double lastResidual() const override { return residual_; }

  void step(const SystemView& system, const ForceModel& forces, double dt) override {
    const bool topology_changed = !structure_.matches(system);
    if (topology_changed) resize(system);
    const std::size_t n = structure_.padded;
    const std::size_t m = system.spring_count;
    const std::uint32_t* order = structure_.order.data();
    const double h = dt;
    const double h2 = dt * dt;

    forces.compute(system, system.positions, system.velocities, forces_.data());
    // Node terms in internal order: anchor_term = Δt²·k_anchor (its part of Δt²·S), node_term = m + Δt·c +
    // anchor_term; the padding lanes beyond node_count stay constrained zeros.
    double* anchor_term = anchor_term_.data();
    double* node_term = node_term_.data();
    double* mask = mask_.data();
    double* v0 = p_.data();
    std::fill(anchor_term, anchor_term + n, 0.0);
    for (const Anchor& anchor : forces.anchors) anchor_term[structure_.internal[anchor.node]] += h2 * anchor.stiffness;
    const double damping = h * forces.params.damping;
    for (std::size_t k = 0; k < system.node_count; ++k) {
      const std::uint32_t i = order[k];
      node_term[k] = system.masses[i] + damping + anchor_term[k];
      mask[k] = system.isFree(i) ? 1.0 : 0.0;
      const Eigen::Vector3d& v = system.velocities[i];
      v0[k] = v.x();
      v0[n + k] = v.y();
      v0[2 * n + k] = v.z();
    }
    for (int c = 0; c < 3; ++c) std::copy(node_term, node_term + n, node_blocks_[c].data());
    for (int c = 3; c < 6; ++c) std::fill(node_blocks_[c].begin(), node_blocks_[c].end(), 0.0);

    springBlocks(m, structure_.spring_order.data(), system.springs, system.positions, system.stiffnesses,
                 system.rest_lengths, h2, spring_blocks_[4].data(), spring_blocks_[5].data(), spring_blocks_[0].data(),
                 spring_blocks_[1].data(), spring_blocks_[2].data(), spring_blocks_[3].data());
    const std::uint32_t* group_slots = structure_.group_slots.data();
    const std::int32_t* first_neighbour = structure_.first_neighbour.data();
    const std::uint32_t* neighbour = structure_.neighbour.data();
    const Springs springs{spring_blocks_[0].data(),
                          spring_blocks_[1].data(),
                          spring_blocks_[2].data(),
                          spring_blocks_[3].data(),
                          structure_.first_spring.data(),
                          structure_.spring.data(),
                          mask};
    nodeBlocks(n / kLanes, group_slots, springs, node_blocks_[0].data(), node_blocks_[1].data(), node_blocks_[2].data(),
               node_blocks_[3].data(), node_blocks_[4].data(), node_blocks_[5].data());
    invertNodeBlocks(n, preconditioner_, mask, node_blocks_[0].data(), node_blocks_[1].data(), node_blocks_[2].data(),
                     node_blocks_[3].data(), node_blocks_[4].data(), node_blocks_[5].data());

    // b = mask·(Δt·F⁰ − Δt²·S v⁰).
    double* q = q_.data();
    double* r = r_.data();
    product(n, group_slots, first_neighbour, neighbour, springs, anchor_term, v0, q);
    double b_norm2 = 0.0;
    for (std::size_t k = 0; k < system.node_count; ++k) {
      const Eigen::Vector3d& f = forces_[order[k]];
      for (int c = 0; c < 3; ++c) {
        const std::size_t index = c * n + k;
        r[index] = mask[k] * (h * f[c] - q[index]);
        b_norm2 += r[index] * r[index];
      }
    }

    // Warm start: the last Δv, scaled by dt / previous dt (Δv ≈ Δt·acceleration), r = b − A·Δv₀.
    double* dv = dv_.data();
    const bool warm = options_.cg_warm_start && !topology_changed && previous_dt_ > 0.0;
    if (warm) {
      const double scale = dt / previous_dt_;
      for (int c = 0; c < 3; ++c) {
        for (std::size_t k = 0; k < n; ++k) dv[c * n + k] *= scale * mask[k];
      }
      product(n, group_slots, first_neighbour, neighbour, springs, node_term, dv, q);
      for (std::size_t k = 0; k < 3 * n; ++k) r[k] -= q[k];
    } else {
      std::fill(dv, dv + 3 * n, 0.0);
    }

    const NodeBlocks inverse{node_blocks_[0].data(), node_blocks_[1].data(), node_blocks_[2].data(),
                             node_blocks_[3].data(), node_blocks_[4].data(), node_blocks_[5].data()};
    const SolveResult result =
        solve(preconditioner_, n, group_slots, first_neighbour, neighbour, springs, node_term, inverse, b_norm2, r,
              z_.data(), p_.data(), q, dv, options_.cg_max_iterations, options_.cg_tolerance);
    iterations_ = result.iterations;
    residual_ = result.residual;
    previous_dt_ = dt;

    for (std::size_t k = 0; k < system.node_count; ++k) {
      if (mask[k] == 0.0) continue;
      const std::uint32_t i = order[k];
      Eigen::Vector3d& v = system.velocities[i];
      v += Eigen::Vector3d(dv[k], dv[n + k], dv[2 * n + k]);
      system.positions[i] += h * v;
    }
  }

 private:
  void resize(const SystemView& system) {
    structure_.build(system);
    const std::size_t n = structure_.padded;
    forces_.assign(system.node_count, Eigen::Vector3d::Zero());
    for (auto* vector : {&r_, &z_, &p_, &q_, &dv_}) vector->assign(3 * n, 0.0);
    for (auto* vector : {&anchor_term_, &node_term_, &mask_}) vector->assign(n, 0.0);
    for (auto& block : node_blocks_) block.assign(n, 0.0);
    for (auto& block : spring_blocks_) block.assign(system.spring_count + 1, 0.0);
    previous_dt_ = 0.0;
  }

  IntegratorOptions options_;
  Preconditioner preconditioner_;
  int iterations_ = 0;
  double residual_ = 0.0;
  double previous_dt_ = 0.0;  // of the last solve (warm start); 0 after a topology change
  Structure structure_;
  std::vector<Eigen::Vector3d> forces_;
  std::vector<double> r_, z_, p_, q_, dv_;  // [x|y|z], stride structure_.padded
  std::vector<double> anchor_term_, node_term_, mask_;
  std::array<std::vector<double>, 6> node_blocks_;  // xx, yy, zz, xy, xz, yz of A, then of the preconditioner
  // a, v_x, v_y, v_z per internal spring id (+ one zero block), then stiffness and rest length in that order.
  std::array<std::vector<double>, 6> spring_blocks_;
};

}  // namespace

std::unique_ptr<Integrator> makeImplicitEuler(const IntegratorOptions& options) {
  return std::make_unique<ImplicitEuler>(options);
}

}  // namespace tissue
}  // namespace vrm_sim
