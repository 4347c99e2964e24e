#include "geometry/aabb_tree.hpp"

#include <algorithm>
#include <stdexcept>

namespace diffavatar {

void AabbTree::build(const std::vector<Box>& boxes, int leaf_size) {
  nodes_.clear();
  order_.resize(boxes.size());
  if (boxes.empty()) return;
  std::vector<Vec3> centers(boxes.size());
  for (size_t i = 0; i < boxes.size(); ++i) {
    order_[i] = static_cast<int>(i);
    centers[i] = boxes[i].center();
  }
  nodes_.reserve(2 * boxes.size() / std::max(1, leaf_size) + 2);
  build_range(boxes, centers, 0, static_cast<int>(boxes.size()), std::max(1, leaf_size), 0);
}

int AabbTree::build_range(const std::vector<Box>& boxes, std::vector<Vec3>& centers, int start,
                          int end, int leaf_size, int depth) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  Box box;
  box.setEmpty();
  Box cbox;
  cbox.setEmpty();
  for (int k = start; k < end; ++k) {
    box.extend(boxes[order_[k]]);
    cbox.extend(centers[order_[k]]);
  }
  nodes_[id].box = box;
  // depth cap keeps the traversal stack (128) safe: median splits give depth ~log2(n)
  if (end - start <= leaf_size || depth >= 60) {
    nodes_[id].start = start;
    nodes_[id].count = end - start;
    return id;
  }
  int axis;
  cbox.sizes().maxCoeff(&axis);
  const int mid = (start + end) / 2;
  std::nth_element(order_.begin() + start, order_.begin() + mid, order_.begin() + end,
                   [&](int a, int b) { return centers[a][axis] < centers[b][axis]; });
  const int l = build_range(boxes, centers, start, mid, leaf_size, depth + 1);
  const int r = build_range(boxes, centers, mid, end, leaf_size, depth + 1);
  nodes_[id].left = l;
  nodes_[id].right = r;
  return id;
}

void AabbTree::refit(const std::vector<Box>& boxes) {
  if (boxes.size() != order_.size()) throw std::invalid_argument("AabbTree::refit: primitive count changed");
  // children are created after their parent, so a reverse sweep visits children first
  for (int id = static_cast<int>(nodes_.size()) - 1; id >= 0; --id) {
    Node& n = nodes_[id];
    n.box.setEmpty();
    if (n.count > 0) {
      for (int k = n.start; k < n.start + n.count; ++k) n.box.extend(boxes[order_[k]]);
    } else {
      n.box.extend(nodes_[n.left].box);
      n.box.extend(nodes_[n.right].box);
    }
  }
}

}  // namespace diffavatar
