#pragma once
// Spreading detected corners evenly over an image region with a quadtree (as ORB-SLAM does):
// nodes are split into four children, largest nodes first, until there are as many non-empty
// nodes as wanted or no node holds more than one corner; each node then keeps its strongest
// corner.

#include <opencv2/core.hpp>
#include <vector>

namespace superdyna::features {

/// Indices (ascending) of at most `target` corners spread over `region` [px]. The region starts
/// as round(width / height) side-by-side root nodes (at least one). Nodes are split in order of
/// decreasing area, then decreasing corner count, then creation order (so splitting proceeds
/// level by level, densest nodes first); empty children are dropped and nodes with a single
/// corner are not split. When the last split overshoots the target, the children of that split
/// with the weakest winners are dropped. Each remaining node keeps its strongest corner (ties in
/// response go to the lower index). Corners outside `region` are ignored; when at most `target`
/// lie inside, all of them are returned. Deterministic.
std::vector<int> distributeQuadtree(const std::vector<cv::KeyPoint>& corners,
                                    const cv::Rect2f& region, int target);

}  // namespace superdyna::features
