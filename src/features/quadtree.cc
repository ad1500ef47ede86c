#include "superdyna/features/quadtree.h"

#include <algorithm>
#include <cmath>
#include <queue>

namespace superdyna::features {

namespace {

/// Nodes narrower than this cannot separate integer pixel positions any further [px].
constexpr float kMinNodeSide = 1.0f;

struct Node {
  float x0, y0, x1, y1;  ///< Bounds [px]: x0 <= x < x1 (the root's far edges are inclusive).
  std::vector<int> members;
  int id;  ///< Creation order, for deterministic tie-breaking.

  float area() const { return (x1 - x0) * (y1 - y0); }
  bool splittable() const {
    return members.size() > 1 && x1 - x0 >= kMinNodeSide && y1 - y0 >= kMinNodeSide;
  }
};

/// Priority of splitting: larger area first, then more members, then older.
struct SplitOrder {
  const std::vector<Node>* nodes;
  bool operator()(int a, int b) const {  // true when a comes after b
    const Node& na = (*nodes)[static_cast<std::size_t>(a)];
    const Node& nb = (*nodes)[static_cast<std::size_t>(b)];
    if (na.area() != nb.area()) return na.area() < nb.area();
    if (na.members.size() != nb.members.size()) return na.members.size() < nb.members.size();
    return na.id > nb.id;
  }
};

/// The four children of `parent` with its members distributed (empty ones included).
std::array<Node, 4> splitNode(const Node& parent, const std::vector<cv::KeyPoint>& corners) {
  const float xm = 0.5f * (parent.x0 + parent.x1);
  const float ym = 0.5f * (parent.y0 + parent.y1);
  std::array<Node, 4> children = {
      Node{parent.x0, parent.y0, xm, ym, {}, 0}, Node{xm, parent.y0, parent.x1, ym, {}, 0},
      Node{parent.x0, ym, xm, parent.y1, {}, 0}, Node{xm, ym, parent.x1, parent.y1, {}, 0}};
  for (const int i : parent.members) {
    const cv::Point2f& p = corners[static_cast<std::size_t>(i)].pt;
    const int quadrant = (p.x < xm ? 0 : 1) + (p.y < ym ? 0 : 2);
    children[static_cast<std::size_t>(quadrant)].members.push_back(i);
  }
  return children;
}

/// The strongest member of a node (lowest index among equals).
int strongest(const Node& node, const std::vector<cv::KeyPoint>& corners) {
  int best = node.members.front();
  for (const int i : node.members) {
    if (corners[static_cast<std::size_t>(i)].response >
        corners[static_cast<std::size_t>(best)].response) {
      best = i;
    }
  }
  return best;
}

/// Root nodes: round(width / height) columns (at least one) spanning the region.
std::vector<Node> rootNodes(const std::vector<cv::KeyPoint>& corners, const cv::Rect2f& region) {
  const int count =
      std::max(1, static_cast<int>(std::lround(region.width / std::max(region.height, 1.0f))));
  const float width = region.width / static_cast<float>(count);
  std::vector<Node> roots;
  for (int k = 0; k < count; ++k) {
    const float x0 = region.x + k * width;
    roots.push_back({x0, region.y, x0 + width, region.y + region.height, {}, k});
  }
  for (std::size_t i = 0; i < corners.size(); ++i) {
    const cv::Point2f& p = corners[i].pt;
    if (p.x < region.x || p.y < region.y || p.x > region.x + region.width ||
        p.y > region.y + region.height) {
      continue;
    }
    const int k = std::clamp(static_cast<int>((p.x - region.x) / width), 0, count - 1);
    roots[static_cast<std::size_t>(k)].members.push_back(static_cast<int>(i));
  }
  std::erase_if(roots, [](const Node& node) { return node.members.empty(); });
  return roots;
}

}  // namespace

std::vector<int> distributeQuadtree(const std::vector<cv::KeyPoint>& corners,
                                    const cv::Rect2f& region, int target) {
  if (target <= 0 || corners.empty()) return {};
  std::vector<Node> nodes = rootNodes(corners, region);
  std::vector<bool> is_leaf(nodes.size(), true);
  std::priority_queue<int, std::vector<int>, SplitOrder> queue(SplitOrder{&nodes});
  int next_id = static_cast<int>(nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    if (nodes[k].splittable()) queue.push(static_cast<int>(k));
  }
  std::size_t leaves = nodes.size();
  std::vector<std::size_t> last_children;  ///< Nodes created by the latest split.
  while (leaves < static_cast<std::size_t>(target) && !queue.empty()) {
    const int parent = queue.top();
    queue.pop();
    const auto children = splitNode(nodes[static_cast<std::size_t>(parent)], corners);
    is_leaf[static_cast<std::size_t>(parent)] = false;
    nodes[static_cast<std::size_t>(parent)].members = {};
    --leaves;
    last_children.clear();
    for (const Node& child : children) {
      if (child.members.empty()) continue;
      nodes.push_back(child);
      nodes.back().id = next_id++;
      is_leaf.push_back(true);
      last_children.push_back(nodes.size() - 1);
      ++leaves;
      if (nodes.back().splittable()) queue.push(static_cast<int>(nodes.size()) - 1);
    }
  }
  // The last split may overshoot the target by up to 3: drop its weakest children. (Without any
  // split, only the roots can outnumber the target: drop the weakest roots.)
  if (leaves > static_cast<std::size_t>(target)) {
    std::vector<std::size_t> droppable = last_children;
    if (droppable.empty()) {
      for (std::size_t k = 0; k < nodes.size(); ++k) {
        if (is_leaf[k]) droppable.push_back(k);
      }
    }
    std::stable_sort(droppable.begin(), droppable.end(), [&](std::size_t a, std::size_t b) {
      return corners[static_cast<std::size_t>(strongest(nodes[a], corners))].response <
             corners[static_cast<std::size_t>(strongest(nodes[b], corners))].response;
    });
    const std::size_t excess =
        std::min(leaves - static_cast<std::size_t>(target), droppable.size());
    for (std::size_t k = 0; k < excess; ++k)
      is_leaf[droppable[k]] = false;
  }

  std::vector<int> chosen;
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    if (is_leaf[k]) chosen.push_back(strongest(nodes[k], corners));
  }
  std::sort(chosen.begin(), chosen.end());
  return chosen;
}

}  // namespace superdyna::features
