// A* over the global planner's cell grid, for the searches around temporary obstacles that
// the small box search (planner_grid.box_field) cannot settle.
//
// The planner (spqrel_nav_lite/planner.py) has, for every patrol goal, the obstacle-free
// navigation function d_free(x) (cost from cell x to the goal without temporary obstacles,
// cached and shared by the robots of a process). Temporary obstacles only remove cells, so
// d_free is a consistent lower bound of the cost with them: A* from the robot's cell guided
// by it finds the optimal cost and expands little more than the cells of the detour the
// obstacles force (a search from the goal would have no such bound of the cost to the
// robot's cell: |d_free(s) - d_free(x)| ties every cell nearer the goal than the robot).
// Among the equally cheap paths it returns the one a Dijkstra field from the goal gives: a
// second, small search over the cheapest paths' cells (below).
// scipy's Dijkstra (the planner's fallback without this library, see grid_search.py) must
// search a window around start and goal, or the whole map, and the window's graph must be
// built first; no library in Debian offers A* with a per-cell heuristic on this graph (the
// grid's edge costs and corner rule below), hence this file (docs/navigation.md, "Planning
// around other robots").
//
// The graph is the one of planner_grid.PlannerGrid: 8-connected cells, a cell usable if it is
// neither lethal nor a temporary obstacle, a diagonal move allowed only if neither of the two
// cells it passes is lethal (outside the grid counts as lethal), edge weight
// length * 0.5 * (cost_a + cost_b) with length res or res * sqrt(2) as given by the caller.
//
// Plain C interface (called through ctypes, which releases the GIL during the call).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <queue>

namespace {

struct Entry {
  double f;    // cost from the start + heuristic
  double h;    // heuristic (ties: the entry nearer the goal first)
  int64_t cell;
  bool operator<(const Entry& o) const {  // std::priority_queue is a max-heap
    if (f != o.f) return f > o.f;
    return h > o.h;
  }
};

// zero-initialised array whose pages the kernel maps only when touched (calloc of a large
// block), so a search that expands a few hundred cells of a large grid costs no O(cells)
// initialisation
template <typename T>
struct LazyArray {
  T* p;
  explicit LazyArray(int64_t n) : p(static_cast<T*>(std::calloc(n > 0 ? n : 1, sizeof(T)))) {}
  ~LazyArray() { std::free(p); }
  LazyArray(const LazyArray&) = delete;
  LazyArray& operator=(const LazyArray&) = delete;
};

// Calls f(nb, weight) for every move of the planner's cell graph out of cell c (w x h grid):
// the 8 neighbours inside the grid, a diagonal only if neither cell it passes is lethal, the
// weight length * 0.5 * (cost[c] + cost[nb]). Whether nb itself is usable is the caller's test.
template <typename F>
inline void for_each_move(int64_t c, int64_t w, int64_t h, const uint8_t* lethal,
                          const double* cost, double len_straight, double len_diag, F&& f) {
  static const int DI[8] = {-1, 0, 1, -1, 1, -1, 0, 1};
  static const int DJ[8] = {-1, -1, -1, 0, 0, 1, 1, 1};
  const int64_t ci = c % w, cj = c / w;
  for (int k = 0; k < 8; ++k) {
    const int64_t ni = ci + DI[k], nj = cj + DJ[k];
    if (ni < 0 || ni >= w || nj < 0 || nj >= h) continue;
    const bool diagonal = DI[k] != 0 && DJ[k] != 0;
    if (diagonal && (lethal[cj * w + ni] || lethal[nj * w + ci])) continue;
    const int64_t nb = nj * w + ni;
    f(nb, (diagonal ? len_diag : len_straight) * 0.5 * (cost[c] + cost[nb]));
  }
}

}  // namespace

extern "C" {

// Optimal path from cell s to cell g (cell index = row * w + column).
//   lethal, obstacles: w*h bytes, non-zero = forbidden (lethal also forbids corner cutting)
//   cost: w*h doubles (>= 1), heur: w*h floats, a consistent lower bound of the cost to g
//         (infinite where g cannot be reached)
//   path: room for max_path cell indices; on success it holds s ... g
// Returns the number of path cells, 0 if g cannot be reached from s, -1 if the path has more
// than max_path cells, -2 on bad arguments or no memory. *path_cost gets the path's cost (sum
// of its edge weights, from g), *expanded the number of cells expanded by both searches.
int64_t spqrel_grid_astar(int64_t w, int64_t h, const uint8_t* lethal, const uint8_t* obstacles,
                          const double* cost, const float* heur, double len_straight,
                          double len_diag, int64_t s, int64_t g, int32_t* path, int64_t max_path,
                          double* path_cost, int64_t* expanded) {
  const int64_t n = w * h;
  *expanded = 0;
  *path_cost = std::numeric_limits<double>::infinity();
  if (w <= 0 || h <= 0 || s < 0 || s >= n || g < 0 || g >= n || max_path < 1) return -2;
  if (lethal[s] || obstacles[s] || lethal[g] || obstacles[g] || !std::isfinite(heur[s])) return 0;
  enum : uint8_t { UNSEEN = 0, OPEN = 1, CLOSED = 2 };
  LazyArray<double> gval(n);     // cost from s (valid once the cell is OPEN)
  LazyArray<int32_t> parent(n);  // the previous cell of the best path found so far
  LazyArray<uint8_t> state(n);
  if (!gval.p || !parent.p || !state.p) return -2;
  std::priority_queue<Entry> open;
  gval.p[s] = 0.0;
  state.p[s] = OPEN;
  open.push({static_cast<double>(heur[s]), static_cast<double>(heur[s]), s});
  bool found = false;
  while (!open.empty()) {
    const Entry e = open.top();
    open.pop();
    const int64_t c = e.cell;
    if (state.p[c] == CLOSED) continue;   // an outdated entry
    state.p[c] = CLOSED;
    ++*expanded;
    if (c == g) {
      found = true;
      break;
    }
    const double gc = gval.p[c];
    for_each_move(c, w, h, lethal, cost, len_straight, len_diag, [&](int64_t nb, double wt) {
      if (lethal[nb] || obstacles[nb] || state.p[nb] == CLOSED) return;
      const double hn = heur[nb];
      if (!std::isfinite(hn)) return;     // no path from there to g at all
      const double ng = gc + wt;
      if (state.p[nb] == OPEN && ng >= gval.p[nb]) return;
      state.p[nb] = OPEN;
      gval.p[nb] = ng;
      parent.p[nb] = static_cast<int32_t>(c);
      open.push({ng + hn, hn, nb});
    });
  }
  if (!found) return 0;
  // The path. A* settles ties between equally cheap paths in favour of the cells its
  // heuristic ranks first: those of the obstacle-free path, so its path follows that one up
  // to the obstacle and swerves at the last moment, passing the other robot at the least
  // allowed distance for longer (12 robots on grid: a third more stops in front of a robot,
  // docs/navigation.md). The path is therefore taken from a Dijkstra search from g over the
  // cells that lie on a cheapest path (cost from g plus A*'s exact cost from s equal to the
  // optimum): settled in order of cost to g and each cell linked to its first settled
  // neighbour, as the planner's Dijkstra fields (the box search, the window search) link
  // them, so that a robot leaves the obstacle-free path as early as a cheapest path allows.
  // The cells of A*'s own path are closed (exact costs from s), so s is always reached.
  const double best = gval.p[g];
  const double slack = 1e-9 * best + 1e-9;   // summation order: costs equal to rounding
  LazyArray<double> back(n);      // cost to g (valid once the cell is reached)
  LazyArray<int32_t> next(n);     // the next cell towards g
  LazyArray<uint8_t> bstate(n);
  if (!back.p || !next.p || !bstate.p) return -2;
  struct Item {
    double d;
    int64_t cell;
    bool operator<(const Item& o) const { return d > o.d; }
  };
  std::priority_queue<Item> queue;
  back.p[g] = 0.0;
  bstate.p[g] = OPEN;
  queue.push({0.0, g});
  bool reached = false;
  while (!queue.empty()) {
    const Item it = queue.top();
    queue.pop();
    const int64_t c = it.cell;
    if (bstate.p[c] == CLOSED) continue;
    bstate.p[c] = CLOSED;
    ++*expanded;
    if (c == s) {
      reached = true;
      break;
    }
    const double dc = back.p[c];
    for_each_move(c, w, h, lethal, cost, len_straight, len_diag, [&](int64_t nb, double wt) {
      // only cells A* reached (their cost from s is known: exact if closed, else an upper
      // bound, which can only leave a tied cell out); the moves are symmetric
      if (state.p[nb] == UNSEEN || bstate.p[nb] == CLOSED) return;
      const double nd = dc + wt;
      if (nd + gval.p[nb] > best + slack) return;     // not on a cheapest path
      if (bstate.p[nb] == OPEN && nd >= back.p[nb]) return;
      bstate.p[nb] = OPEN;
      back.p[nb] = nd;
      next.p[nb] = static_cast<int32_t>(c);
      queue.push({nd, nb});
    });
  }
  if (!reached) {   // not expected (A*'s own path qualifies): A*'s path, then
    for (int64_t c = g; c != s; c = parent.p[c]) next.p[parent.p[c]] = static_cast<int32_t>(c);
    back.p[s] = best;
  }
  int64_t len = 1;
  for (int64_t c = s; c != g; c = next.p[c]) ++len;
  if (len > max_path) return -1;
  int64_t k = 0;
  for (int64_t c = s;; c = next.p[c]) {
    path[k++] = static_cast<int32_t>(c);
    if (c == g) break;
  }
  *path_cost = back.p[s];
  return len;
}

}  // extern "C"
