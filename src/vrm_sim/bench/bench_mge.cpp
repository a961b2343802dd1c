// bench_mge: cost of the MGE data model (thesis §3.3) against plain layouts, on a triangulated grid (degree ~6).
//   sweep:      update + sum every node position. mge = ArrayManager column; std_vector = std::vector<Vector3d>;
//               pointer_per_node = one heap object per node, allocated in shuffled order (an edited, long-lived
//               graph, §3.3 "Speicherfragmentierung"), visited through a vector of pointers in grid order.
//   navigation: Laplacian-like sum over each node's neighbours. mge = ListAccess over the tissue's node list and
//               over each node's neighbour lists (label and reference label), positions through the ArrayManager;
//               mge_neighbour_slots = the same neighbourhoods through NeighbourSlots (the MGE's derived slot array,
//               rebuilt from ListAccess on topology change, issue 15); csr = offsets + indices into a position vector;
//               pointer_per_node = neighbour pointers.
//   neighbour_slots_build: one NeighbourSlots rebuild (what a topology change costs), ns per node.
// Sweep: median ns per node over several timed samples. Navigation: kNavigationRepetitions repetitions in one run,
// all implementations measured back to back inside each repetition (drifting load on a shared machine hits them
// alike); each repetition is the median of a few samples; reported are the median over the repetitions, their
// spread (min, max) and the per-repetition ratio mge/csr. Usage: bench_mge [--quick] [--out FILE]

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <memory>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "vrm_sim/mge/elements.h"
#include "vrm_sim/mge/graph.h"
#include "vrm_sim/mge/labels.h"
#include "vrm_sim/mge/list_access.h"
#include "vrm_sim/mge/neighbour_slots.h"

namespace {

using Eigen::Vector3d;
using vrm_sim::mge::Graph;
using vrm_sim::mge::ListAccess;
using vrm_sim::mge::NeighbourSlots;
using vrm_sim::mge::Node;
using vrm_sim::mge::NodeArrays;
using vrm_sim::mge::Tissue;

constexpr vrm_sim::mge::Label kMeshNeighbour = vrm_sim::mge::labels::kFirstUserLabel;

// Results flow into this sink so the compiler cannot drop the measured work.
volatile double g_sink = 0.0;

struct Spread {
  double median = NAN;
  double min = NAN;
  double max = NAN;
};

Spread spreadOf(std::vector<double> values) {
  Spread spread;
  if (values.empty()) return spread;
  std::sort(values.begin(), values.end());
  spread.min = values.front();
  spread.max = values.back();
  const std::size_t n = values.size();
  spread.median = n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
  return spread;
}

struct Row {
  std::string kind;
  std::size_t elements;
  std::string impl;
  double ns_per_element;
  std::size_t edges;
  int repetitions;
  int passes;
  Spread spread;        // navigation: over the repetitions (ns per node)
  Spread ratio_to_csr;  // navigation: per-repetition ns / csr ns
};

constexpr int kNavigationRepetitions = 5;
constexpr int kSamplesPerRepetition = 3;

// w×w grid, edges right, up and diagonal (the triangulation of the membrane tests): interior degree 6.
struct GridGraph {
  int width = 0;
  std::size_t nodes() const { return static_cast<std::size_t>(width) * width; }
  template <typename Visit>
  void forEachEdge(Visit visit) const {
    for (int j = 0; j < width; ++j) {
      for (int i = 0; i < width; ++i) {
        const std::uint32_t v = j * width + i;
        if (i + 1 < width) visit(v, v + 1);
        if (j + 1 < width) visit(v, v + width);
        if (i + 1 < width && j + 1 < width) visit(v, v + width + 1);
      }
    }
  }
  Vector3d position(std::uint32_t v) const { return Vector3d(v % width, v / width, 0.01 * (v % 7)); }
};

template <typename Kernel>
double sampleNsPerElement(Kernel& kernel, std::size_t elements, int passes) {
  const auto start = std::chrono::steady_clock::now();
  for (int p = 0; p < passes; ++p) kernel();
  const auto stop = std::chrono::steady_clock::now();
  return std::chrono::duration<double, std::nano>(stop - start).count() / (static_cast<double>(elements) * passes);
}

template <typename Kernel>
double medianNsPerElement(Kernel kernel, std::size_t elements, int repetitions, int passes) {
  kernel();  // warm-up
  std::vector<double> samples;
  for (int r = 0; r < repetitions; ++r) {
    const auto start = std::chrono::steady_clock::now();
    for (int p = 0; p < passes; ++p) kernel();
    const auto stop = std::chrono::steady_clock::now();
    samples.push_back(std::chrono::duration<double, std::nano>(stop - start).count() /
                      (static_cast<double>(elements) * passes));
  }
  std::nth_element(samples.begin(), samples.begin() + samples.size() / 2, samples.end());
  return samples[samples.size() / 2];
}

// ---- pointer_per_node baseline ----
struct PointerNode {
  Vector3d position;
  Vector3d laplacian;
  std::vector<PointerNode*> neighbours;
};

struct PointerGraph {
  std::vector<std::unique_ptr<PointerNode>> storage;  // allocation order (shuffled)
  std::vector<PointerNode*> nodes;                    // grid order
};

PointerGraph buildPointerGraph(const GridGraph& grid, std::uint32_t seed) {
  PointerGraph graph;
  const std::size_t n = grid.nodes();
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::shuffle(order.begin(), order.end(), std::mt19937(seed));
  graph.nodes.assign(n, nullptr);
  graph.storage.reserve(n);
  for (std::uint32_t v : order) {
    graph.storage.push_back(std::make_unique<PointerNode>());
    graph.storage.back()->position = grid.position(v);
    graph.nodes[v] = graph.storage.back().get();
  }
  // Neighbour vectors also grow in shuffled order, as edits scatter them.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;
  grid.forEachEdge([&edges](std::uint32_t a, std::uint32_t b) { edges.emplace_back(a, b); });
  std::shuffle(edges.begin(), edges.end(), std::mt19937(seed + 1));
  for (const auto& [a, b] : edges) {
    graph.nodes[a]->neighbours.push_back(graph.nodes[b]);
    graph.nodes[b]->neighbours.push_back(graph.nodes[a]);
  }
  return graph;
}

// ---- csr baseline ----
struct CsrGraph {
  std::vector<std::uint32_t> offsets;
  std::vector<std::uint32_t> indices;
  std::vector<Vector3d> positions;
  std::vector<Vector3d> laplacian;
};

CsrGraph buildCsr(const GridGraph& grid) {
  CsrGraph csr;
  const std::size_t n = grid.nodes();
  std::vector<std::vector<std::uint32_t>> adjacency(n);
  grid.forEachEdge([&adjacency](std::uint32_t a, std::uint32_t b) {
    adjacency[a].push_back(b);
    adjacency[b].push_back(a);
  });
  csr.offsets.push_back(0);
  for (const auto& list : adjacency) {
    csr.indices.insert(csr.indices.end(), list.begin(), list.end());
    csr.offsets.push_back(static_cast<std::uint32_t>(csr.indices.size()));
  }
  for (std::uint32_t v = 0; v < n; ++v) csr.positions.push_back(grid.position(v));
  csr.laplacian.assign(n, Vector3d::Zero());
  return csr;
}

// ---- mge ----
struct MgeGraph {
  // The graph is declared last, so it dies first and its nodes release their slots while the arrays still exist.
  NodeArrays arrays;
  std::vector<Vector3d> laplacian;
  Graph graph;
  Tissue* tissue = nullptr;
};

std::unique_ptr<MgeGraph> buildMge(const GridGraph& grid) {
  auto mge = std::make_unique<MgeGraph>();
  const std::size_t n = grid.nodes();
  mge->arrays.reserve(n);
  mge->tissue = &mge->graph.create<Tissue>();
  std::vector<Node*> nodes;
  nodes.reserve(n);
  for (std::uint32_t v = 0; v < n; ++v) {
    Node& node = mge->graph.create<Node>();
    node.arrayConnector().connect(mge->arrays, &node, grid.position(v), Vector3d::Zero(), 1.0, 0);
    mge->graph.insertEdge(*mge->tissue, node, vrm_sim::mge::labels::kNodeList);
    nodes.push_back(&node);
  }
  grid.forEachEdge(
      [&](std::uint32_t a, std::uint32_t b) { mge->graph.insertEdge(*nodes[a], *nodes[b], kMeshNeighbour); });
  mge->graph.shrinkToFit();
  mge->laplacian.assign(n, Vector3d::Zero());
  return mge;
}

// ---- kernels ----
const Vector3d kDelta(1e-9, -2e-9, 3e-9);

__attribute__((noinline)) double sweepArray(Vector3d* positions, std::size_t count) {
  double sum = 0.0;
  for (std::size_t i = 0; i < count; ++i) {
    positions[i] += kDelta;
    sum += positions[i].x();
  }
  return sum;
}

__attribute__((noinline)) double sweepPointers(const std::vector<PointerNode*>& nodes) {
  double sum = 0.0;
  for (PointerNode* node : nodes) {
    node->position += kDelta;
    sum += node->position.x();
  }
  return sum;
}

__attribute__((noinline)) double navigateMge(MgeGraph& mge) {
  const Vector3d* positions = mge.arrays.data<vrm_sim::mge::kNodePosition>();
  Vector3d* laplacian = mge.laplacian.data();
  for (Node* node : ListAccess<Node>(*mge.tissue, vrm_sim::mge::labels::kNodeList)) {
    const std::uint32_t slot = node->slot();
    const Vector3d& center = positions[slot];
    Vector3d sum = Vector3d::Zero();
    // Mesh edges were inserted once per pair, so a node's neighbours sit under the label and its reference label.
    for (Node* neighbour : ListAccess<Node>(*node, kMeshNeighbour)) sum += positions[neighbour->slot()] - center;
    for (Node* neighbour : ListAccess<Node>(*node, -kMeshNeighbour)) sum += positions[neighbour->slot()] - center;
    laplacian[slot] = sum;
  }
  return laplacian[0].x() + laplacian[mge.laplacian.size() / 2].y();
}

__attribute__((noinline)) double navigateNeighbourSlots(MgeGraph& mge, NeighbourSlots<Node>& view) {
  view.refresh(mge.graph, mge.arrays);  // a version check per sweep; rebuilds only after a topology change
  const Vector3d* positions = mge.arrays.data<vrm_sim::mge::kNodePosition>();
  Vector3d* laplacian = mge.laplacian.data();
  const std::size_t n = view.size();
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t slot = view.slot(k);
    const Vector3d& center = positions[slot];
    Vector3d sum = Vector3d::Zero();
    for (std::uint32_t neighbour : view.neighbours(k)) sum += positions[neighbour] - center;
    laplacian[slot] = sum;
  }
  return laplacian[0].x() + laplacian[mge.laplacian.size() / 2].y();
}

__attribute__((noinline)) double navigateCsr(CsrGraph& csr) {
  const std::size_t n = csr.positions.size();
  const Vector3d* positions = csr.positions.data();
  const std::uint32_t* indices = csr.indices.data();
  for (std::size_t v = 0; v < n; ++v) {
    const Vector3d& center = positions[v];
    Vector3d sum = Vector3d::Zero();
    for (std::uint32_t e = csr.offsets[v]; e < csr.offsets[v + 1]; ++e) sum += positions[indices[e]] - center;
    csr.laplacian[v] = sum;
  }
  return csr.laplacian[0].x() + csr.laplacian[n / 2].y();
}

__attribute__((noinline)) double navigatePointers(PointerGraph& graph) {
  for (PointerNode* node : graph.nodes) {
    Vector3d sum = Vector3d::Zero();
    for (const PointerNode* neighbour : node->neighbours) sum += neighbour->position - node->position;
    node->laplacian = sum;
  }
  return graph.nodes[0]->laplacian.x() + graph.nodes[graph.nodes.size() / 2]->laplacian.y();
}

std::string jsonEscape(const std::string& text) {
  std::string escaped;
  for (char c : text) {
    if (c == '"' || c == '\\') escaped += '\\';
    escaped += c;
  }
  return escaped;
}

void runSize(std::size_t target, bool quick, std::vector<Row>& rows) {
  GridGraph grid;
  grid.width = static_cast<int>(std::lround(std::sqrt(static_cast<double>(target))));
  const std::size_t n = grid.nodes();
  std::size_t edges = 0;
  grid.forEachEdge([&edges](std::uint32_t, std::uint32_t) { ++edges; });
  const int repetitions = quick ? 5 : 9;
  // Enough passes that one sample is ≥ ~4·10^6 node visits (well above the clock resolution).
  const int passes = static_cast<int>(std::max<std::size_t>(1, (quick ? 1000000 : 4000000) / n));
  auto add = [&](const char* kind, const char* impl, double ns) {
    rows.push_back(Row{kind, n, impl, ns, edges, repetitions, passes, Spread{}, Spread{}});
  };

  auto mge = buildMge(grid);
  std::vector<Vector3d> positions;
  for (std::uint32_t v = 0; v < n; ++v) positions.push_back(grid.position(v));
  CsrGraph csr = buildCsr(grid);
  PointerGraph pointers = buildPointerGraph(grid, 12345u + static_cast<std::uint32_t>(n));

  add("sweep", "mge",
      medianNsPerElement(
          [&] { g_sink = g_sink + sweepArray(mge->arrays.data<vrm_sim::mge::kNodePosition>(), mge->arrays.size()); }, n,
          repetitions, passes));
  add("sweep", "std_vector",
      medianNsPerElement([&] { g_sink = g_sink + sweepArray(positions.data(), positions.size()); }, n, repetitions,
                         passes));
  add("sweep", "pointer_per_node",
      medianNsPerElement([&] { g_sink = g_sink + sweepPointers(pointers.nodes); }, n, repetitions, passes));

  struct Navigation {
    const char* impl;
    std::function<void()> kernel;
    std::vector<double> samples;  // one per repetition
  };
  std::vector<Navigation> navigations;
  navigations.push_back({"mge", [&] { g_sink = g_sink + navigateMge(*mge); }, {}});
  NeighbourSlots<Node> view(*mge->tissue, vrm_sim::mge::labels::kNodeList, {kMeshNeighbour, -kMeshNeighbour});
  navigations.push_back({"mge_neighbour_slots", [&] { g_sink = g_sink + navigateNeighbourSlots(*mge, view); }, {}});
  navigations.push_back({"csr", [&] { g_sink = g_sink + navigateCsr(csr); }, {}});
  navigations.push_back({"pointer_per_node", [&] { g_sink = g_sink + navigatePointers(pointers); }, {}});
  for (Navigation& navigation : navigations) navigation.kernel();  // warm-up
  for (int r = 0; r < kNavigationRepetitions; ++r) {
    for (Navigation& navigation : navigations) {
      std::vector<double> samples;
      for (int s = 0; s < kSamplesPerRepetition; ++s)
        samples.push_back(sampleNsPerElement(navigation.kernel, n, passes));
      navigation.samples.push_back(spreadOf(samples).median);
    }
  }
  const std::vector<double>& csr_samples = navigations[2].samples;
  // A rebuild, as after a cut: a fresh view builds on its first refresh.
  add("neighbour_slots_build", "mge",
      medianNsPerElement(
          [&] {
            NeighbourSlots<Node> fresh(*mge->tissue, vrm_sim::mge::labels::kNodeList,
                                       {kMeshNeighbour, -kMeshNeighbour});
            fresh.refresh(mge->graph, mge->arrays);
            g_sink = g_sink + fresh.neighbours(fresh.size() / 2).size();
          },
          n, repetitions, std::max(1, passes / 10)));
  for (const Navigation& navigation : navigations) {
    Row row{"navigation", n, navigation.impl, 0.0, edges, kNavigationRepetitions, passes, spreadOf(navigation.samples),
            Spread{}};
    row.ns_per_element = row.spread.median;
    std::vector<double> ratios;
    for (int r = 0; r < kNavigationRepetitions; ++r) ratios.push_back(navigation.samples[r] / csr_samples[r]);
    row.ratio_to_csr = spreadOf(ratios);
    rows.push_back(row);
  }
}

const Row* findRow(const std::vector<Row>& rows, const std::string& kind, std::size_t elements,
                   const std::string& impl) {
  for (const Row& row : rows) {
    if (row.kind == kind && row.elements == elements && row.impl == impl) return &row;
  }
  return nullptr;
}

double find(const std::vector<Row>& rows, const std::string& kind, std::size_t elements, const std::string& impl) {
  const Row* row = findRow(rows, kind, elements, impl);
  return row == nullptr ? NAN : row->ns_per_element;
}

void jsonSpread(std::ostream& out, const char* name, const Spread& spread) {
  if (std::isnan(spread.median)) return;
  out << ",\"" << name << "\":{\"median\":" << spread.median << ",\"min\":" << spread.min << ",\"max\":" << spread.max
      << "}";
}

}  // namespace

int main(int argc, char** argv) {
  std::string command;
  for (int i = 0; i < argc; ++i) command += (i ? " " : "") + std::string(argv[i]);
  vrm_sim::bench::BenchArgs args;
  if (const auto status = vrm_sim::bench::parseBenchArgs(
          argc, argv, "bench_mge", "The cost of the MGE data model against plain layouts on a triangulated grid.", "",
          &args)) {
    return *status;
  }
  const bool quick = args.quick;
  const std::string out_path = args.out_path;

  const std::vector<std::size_t> sizes =
      quick ? std::vector<std::size_t>{1000, 10000} : std::vector<std::size_t>{1000, 10000, 100000, 1000000};
  std::vector<Row> rows;
  for (std::size_t size : sizes) runSize(size, quick, rows);

  std::printf("bench_mge (%s): median ns per node\n", quick ? "quick" : "full");
  std::printf("%-11s %9s %9s %11s %9s %17s | %15s %21s %9s\n", "case", "elements", "mge", "std_vector", "csr",
              "pointer_per_node", "mge/std_vector", "pointer_per_node/mge", "mge/csr");
  std::vector<std::size_t> seen;
  for (const char* kind : {"sweep", "navigation"}) {
    for (const Row& row : rows) {
      if (row.kind != kind || row.impl != "mge") continue;
      const double mge = row.ns_per_element;
      const double vec = find(rows, kind, row.elements, "std_vector");
      const double csr = find(rows, kind, row.elements, "csr");
      const double ptr = find(rows, kind, row.elements, "pointer_per_node");
      std::printf("%-11s %9zu %9.3f %11.3f %9.3f %17.3f | %15.2f %21.2f %9.2f\n", kind, row.elements, mge, vec, csr,
                  ptr, mge / vec, ptr / mge, mge / csr);
    }
  }
  std::printf("\nnavigation, %d repetitions in this run (each the median of %d samples): median [min, max]\n",
              kNavigationRepetitions, kSamplesPerRepetition);
  std::printf("%9s %-20s %27s %27s\n", "elements", "impl", "ns per node", "ratio to csr (per repetition)");
  for (const Row& row : rows) {
    if (row.kind != "navigation") continue;
    std::printf("%9zu %-20s %9.3f [%7.3f, %7.3f] %9.3f [%7.3f, %7.3f]\n", row.elements, row.impl.c_str(),
                row.spread.median, row.spread.min, row.spread.max, row.ratio_to_csr.median, row.ratio_to_csr.min,
                row.ratio_to_csr.max);
  }
  for (const Row& row : rows) {
    if (row.kind != "neighbour_slots_build") continue;
    std::printf("NeighbourSlots rebuild at %zu elements: %.3f ns per node (%.1f navigation sweeps of the view)\n",
                row.elements, row.ns_per_element,
                row.ns_per_element / find(rows, "navigation", row.elements, "mge_neighbour_slots"));
  }
  std::printf("(checksum %g)\n", static_cast<double>(g_sink));

  if (!out_path.empty()) {
    std::ofstream out(out_path);
    if (!out) {
      std::fprintf(stderr, "cannot write %s\n", out_path.c_str());
      return 1;
    }
    out << "{\"suite\":\"mge\",\"command\":\"" << jsonEscape(command) << "\",\"quick\":" << (quick ? "true" : "false")
        << ",\"rows\":[";
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const Row& row = rows[i];
      out << (i ? "," : "") << "\n  {\"suite\":\"mge\",\"case\":\"" << row.kind << "\",\"elements\":" << row.elements
          << ",\"impl\":\"" << row.impl << "\",\"ns_per_element\":" << row.ns_per_element << ",\"edges\":" << row.edges
          << ",\"repetitions\":" << row.repetitions << ",\"passes\":" << row.passes;
      jsonSpread(out, "ns_spread", row.spread);
      jsonSpread(out, "ratio_to_csr", row.ratio_to_csr);
      out << "}";
    }
    out << "\n]}\n";
  }
  return 0;
}
