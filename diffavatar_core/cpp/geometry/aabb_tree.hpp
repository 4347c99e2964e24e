// Axis-aligned bounding-box tree over arbitrary primitives (points, triangles): built once by
// median splits, refittable when primitives move (a posed or optimized body), queried for the
// closest primitive under an exact distance supplied by the caller.
#pragma once
#include <Eigen/Geometry>
#include <limits>
#include <vector>

#include "common/types.hpp"

namespace diffavatar {

class AabbTree {
 public:
  using Box = Eigen::AlignedBox3d;

  /// Builds the tree over `boxes` (one per primitive). O(n log n).
  void build(const std::vector<Box>& boxes, int leaf_size = 4);
  /// Re-fits node boxes to new primitive boxes (same count, same order); topology kept.
  void refit(const std::vector<Box>& boxes);
  bool empty() const { return nodes_.empty(); }
  int size() const { return static_cast<int>(order_.size()); }

  /// Closest primitive to p. `dist_sq(prim)` returns the exact squared distance from p to the
  /// primitive. Only primitives closer than sqrt(max_sq) are considered. Returns -1 if none;
  /// otherwise the primitive index, with its squared distance in `best_sq`.
  template <class DistSq>
  int closest(const Vec3& p, DistSq&& dist_sq, double max_sq, double& best_sq) const {
    best_sq = max_sq;
    int best = -1;
    if (nodes_.empty()) return best;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& n = nodes_[stack[--top]];
      if (n.box.squaredExteriorDistance(p) >= best_sq) continue;
      if (n.count > 0) {
        for (int k = n.start; k < n.start + n.count; ++k) {
          const int prim = order_[k];
          const double d = dist_sq(prim);
          if (d < best_sq) { best_sq = d; best = prim; }
        }
      } else {
        const double dl = nodes_[n.left].box.squaredExteriorDistance(p);
        const double dr = nodes_[n.right].box.squaredExteriorDistance(p);
        // push the farther child first so the nearer one is visited first
        if (dl < dr) { stack[top++] = n.right; stack[top++] = n.left; }
        else { stack[top++] = n.left; stack[top++] = n.right; }
      }
    }
    return best;
  }

  /// Calls visit(prim) for every primitive whose box intersects `query`.
  template <class Visit>
  void overlapping(const Box& query, Visit&& visit) const {
    if (nodes_.empty()) return;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& n = nodes_[stack[--top]];
      if (!n.box.intersects(query)) continue;
      if (n.count > 0) {
        for (int k = n.start; k < n.start + n.count; ++k) visit(order_[k]);
      } else {
        stack[top++] = n.left;
        stack[top++] = n.right;
      }
    }
  }

 private:
  struct Node {
    Box box;
    int left = -1, right = -1;  // children (internal nodes)
    int start = 0, count = 0;   // range in order_ (leaves: count > 0)
  };
  int build_range(const std::vector<Box>& boxes, std::vector<Vec3>& centers, int start, int end,
                  int leaf_size, int depth);
  std::vector<Node> nodes_;
  std::vector<int> order_;
};

}  // namespace diffavatar
