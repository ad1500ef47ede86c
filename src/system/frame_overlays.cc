#include "superdyna/system/frame_overlays.h"

#include <fmt/format.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <set>
#include <string>
#include <utility>

namespace superdyna::system {

namespace {

// BGR colours of the three decisions and of the keypoints kept or dropped.
const cv::Scalar kMovingColour(0, 0, 255);
const cv::Scalar kStaticColour(0, 200, 0);
const cv::Scalar kUnverifiedColour(0, 220, 255);
const cv::Scalar kKeptColour(0, 200, 0);
const cv::Scalar kDroppedColour(0, 0, 255);
const cv::Scalar kLegendBackground(40, 40, 40);
constexpr double kFontScale = 0.4;
constexpr int kDashPx = 4;  // unverified outlines: 4 px drawn, 4 px left out

/// The instance-id image with only the instances the test found moving (the filled masks).
cv::Mat movingOnly(const cv::Mat& ids, const dynamic::MovingObjectReport& report) {
  if (ids.empty()) return ids;
  std::set<int> moving;
  for (const dynamic::ObjectDecision& object : report.objects)
    if (object.decision == dynamic::ObjectState::kMoving) moving.insert(object.instance_id);
  cv::Mat out = ids.clone();
  out.forEach<std::uint16_t>([&](std::uint16_t& id, const int*) {
    if (id != 0 && !moving.count(id)) id = 0;
  });
  return out;
}

const char* className(int class_id) {
  switch (class_id) {
    case sensors::kInstanceClassVehicle:
      return "vehicle";
    case sensors::kInstanceClassPedestrian:
      return "pedestrian";
    case sensors::kInstanceClassOtherMovable:
      return "movable";
    default:
      return "object";
  }
}

cv::Scalar decisionColour(dynamic::ObjectState state) {
  switch (state) {
    case dynamic::ObjectState::kMoving:
      return kMovingColour;
    case dynamic::ObjectState::kStatic:
      return kStaticColour;
    case dynamic::ObjectState::kUnverified:
      break;
  }
  return kUnverifiedColour;
}

/// Why an object stayed unverified this frame.
std::string unverifiedReason(const dynamic::ObjectDecision& object,
                             const dynamic::MovingObjectOptions& options) {
  if (object.pairs < options.min_pairs) {
    return fmt::format("{} of {} pairs to the previous frame", object.pairs, options.min_pairs);
  }
  return fmt::format("none of its {} pairs testable", object.pairs);
}

/// Text drawn with a dark outline, legible on any background.
void putLabel(cv::Mat& canvas, const std::string& text, cv::Point origin,
              const cv::Scalar& colour) {
  cv::putText(canvas, text, origin, cv::FONT_HERSHEY_SIMPLEX, kFontScale, cv::Scalar(0, 0, 0), 3,
              cv::LINE_AA);
  cv::putText(canvas, text, origin, cv::FONT_HERSHEY_SIMPLEX, kFontScale, colour, 1, cv::LINE_AA);
}

/// The outline of one instance of `ids`: solid, or dashed for an unverified object.
void drawOutline(cv::Mat& canvas, const std::vector<std::vector<cv::Point>>& contours,
                 const cv::Scalar& colour, bool dashed) {
  if (!dashed) {
    cv::drawContours(canvas, contours, -1, colour, 2, cv::LINE_8);
    return;
  }
  for (const std::vector<cv::Point>& contour : contours) {
    for (std::size_t i = 0; i < contour.size(); ++i) {
      if ((i / kDashPx) % 2 != 0) continue;
      cv::circle(canvas, contour[i], 1, colour, cv::FILLED, cv::LINE_8);
    }
  }
}

/// One decided object as drawn: its outline and where its label goes.
struct DrawnObject {
  const dynamic::ObjectDecision* object = nullptr;
  std::vector<std::vector<cv::Point>> contours;
  cv::Point label_origin;
};

/// The decided objects that have pixels in `ids`.
std::vector<DrawnObject> drawnObjects(const cv::Mat& ids,
                                      const dynamic::MovingObjectReport& report) {
  std::vector<DrawnObject> drawn;
  if (ids.empty()) return drawn;
  for (const dynamic::ObjectDecision& object : report.objects) {
    const cv::Mat mask = ids == object.instance_id;
    DrawnObject d{&object, {}, {}};
    cv::findContours(mask, d.contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
    if (d.contours.empty()) continue;
    const cv::Rect box = cv::boundingRect(mask);
    d.label_origin = cv::Point(box.x, box.y > 14 ? box.y - 4 : box.y + box.height + 12);
    drawn.push_back(std::move(d));
  }
  return drawn;
}

/// Every decided object's outline in its decision's style.
void drawOutlines(cv::Mat& canvas, const std::vector<DrawnObject>& objects) {
  for (const DrawnObject& d : objects) {
    drawOutline(canvas, d.contours, decisionColour(d.object->decision),
                d.object->decision == dynamic::ObjectState::kUnverified);
  }
}

/// Where a label of `text_size` goes: at `wanted` or, when it would cover a label already placed,
/// the nearest free line above it (away from its object) or else below, up to three lines away.
cv::Point freeLabelOrigin(cv::Point wanted, cv::Size text_size, cv::Size canvas,
                          const std::vector<cv::Rect>& placed) {
  const int line = text_size.height + 6;
  const auto covers = [&](cv::Point o) {
    const cv::Rect rect(o.x, o.y - text_size.height, text_size.width, line);
    return std::any_of(placed.begin(), placed.end(),
                       [&](const cv::Rect& other) { return (rect & other).area() > 0; });
  };
  const cv::Point start(std::max(0, wanted.x), wanted.y);
  for (const int lines : {0, -1, -2, -3, 1, 2, 3}) {
    const cv::Point origin(start.x, start.y + lines * line);
    if (origin.y < text_size.height || origin.y >= canvas.height) continue;
    if (!covers(origin)) return origin;
  }
  return start;
}

/// Every decided object's label (describeObject), over the keypoints; labels that would overlap
/// are moved apart.
void drawLabels(cv::Mat& canvas, const std::vector<DrawnObject>& objects,
                const dynamic::MovingObjectOptions& options) {
  std::vector<cv::Rect> placed;
  for (const DrawnObject& d : objects) {
    const std::string text = describeObject(*d.object, options);
    int baseline = 0;
    const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, kFontScale, 3, &baseline);
    const cv::Point origin = freeLabelOrigin(d.label_origin, size, canvas.size(), placed);
    placed.emplace_back(origin.x, origin.y - size.height, size.width, size.height + 6);
    putLabel(canvas, text, origin, decisionColour(d.object->decision));
  }
}

void drawKeypoints(cv::Mat& canvas, const std::vector<semantics::LabelledPoint>& points) {
  for (const semantics::LabelledPoint& p : points) {
    const cv::Point centre(cvRound(p.pixel.x), cvRound(p.pixel.y));
    cv::circle(canvas, centre, 3, cv::Scalar(0, 0, 0), cv::FILLED, cv::LINE_AA);
    cv::circle(canvas, centre, 2, p.colour.value_or(kKeptColour), cv::FILLED, cv::LINE_AA);
  }
}

/// The border pixels of `rect`, clockwise from its top-left corner (a contour to dash).
std::vector<cv::Point> perimeter(const cv::Rect& rect) {
  std::vector<cv::Point> points;
  const int right = rect.x + rect.width - 1, bottom = rect.y + rect.height - 1;
  for (int x = rect.x; x < right; ++x)
    points.emplace_back(x, rect.y);
  for (int y = rect.y; y < bottom; ++y)
    points.emplace_back(right, y);
  for (int x = right; x > rect.x; --x)
    points.emplace_back(x, bottom);
  for (int y = bottom; y > rect.y; --y)
    points.emplace_back(rect.x, y);
  return points;
}

/// The key of the three styles and the two keypoint colours, in the top-left corner.
void drawLegend(cv::Mat& canvas) {
  const std::vector<std::pair<std::string, int>> rows = {{"moving object (dropped)", 0},
                                                         {"static object (kept)", 1},
                                                         {"unverified object (reason)", 2},
                                                         {"keypoint kept", 3},
                                                         {"keypoint dropped", 4}};
  constexpr int kRow = 16, kWidth = 200;
  cv::rectangle(canvas, cv::Rect(0, 0, kWidth, kRow * static_cast<int>(rows.size()) + 8),
                kLegendBackground, cv::FILLED);
  for (const auto& [text, style] : rows) {
    const int y = 4 + kRow * style;
    const cv::Rect swatch(6, y + 2, 22, kRow - 5);
    switch (style) {
      case 0:  // the mask filled in its class's colour
        cv::rectangle(canvas, swatch, semantics::classColour(sensors::kInstanceClassVehicle),
                      cv::FILLED);
        cv::rectangle(canvas, swatch, kMovingColour, 2);
        break;
      case 1:
        cv::rectangle(canvas, swatch, kStaticColour, 2);
        break;
      case 2:
        drawOutline(canvas, {perimeter(swatch)}, kUnverifiedColour, true);
        break;
      default:
        drawKeypoints(
            canvas,
            {{{swatch.x + 11.0, y + kRow / 2.0}, 0, style == 3 ? kKeptColour : kDroppedColour}});
    }
    putLabel(canvas, text, cv::Point(36, y + kRow - 4), cv::Scalar(255, 255, 255));
  }
}

}  // namespace

std::string describeObject(const dynamic::ObjectDecision& object,
                           const dynamic::MovingObjectOptions& options) {
  const std::string what = fmt::format("{} {} {}", dynamic::toString(object.decision),
                                       className(object.class_id), object.instance_id);
  if (object.decision != dynamic::ObjectState::kUnverified) return what;
  return fmt::format("{}: {}, {}", what, unverifiedReason(object, options),
                     object.dropped ? "dropped (dynamic.drop_unverified)" : "kept");
}

void FrameOverlays::remember(const sensors::FrameBundle& bundle, const tracking::Frame& frame) {
  if (bundle.index % static_cast<std::size_t>(every_) != 0) return;
  Pending pending{bundle.index, bundle.image0, bundle.masks.value_or(sensors::InstanceMasks{}), {}};
  for (const features::Keypoint& k : frame.features.keypoints)
    pending.points.push_back({{k.pixel.x(), k.pixel.y()}, k.class_id, std::nullopt});
  const std::lock_guard lock(mutex_);
  pending_.emplace(bundle.t_ns, std::move(pending));
}

std::optional<FrameOverlay> FrameOverlays::draw(const tracking::TrackingResult& result) {
  std::optional<Pending> pending;
  {
    const std::lock_guard lock(mutex_);
    const auto found = pending_.find(result.t_ns);
    if (found == pending_.end()) return std::nullopt;
    pending = std::move(found->second);
    pending_.erase(found);
  }
  if (!moving_objects_) {
    return FrameOverlay{pending->index, semantics::drawOverlay(pending->image, pending->masks.cam0,
                                                               pending->masks, pending->points)};
  }
  const std::vector<char>& drop = result.moving.drop;
  for (std::size_t i = 0; i < pending->points.size() && i < drop.size(); ++i)
    pending->points[i].colour = drop[i] ? kDroppedColour : kKeptColour;
  cv::Mat image = semantics::drawOverlay(
      pending->image, movingOnly(pending->masks.cam0, result.moving), pending->masks, {});
  const std::vector<DrawnObject> objects = drawnObjects(pending->masks.cam0, result.moving);
  drawOutlines(image, objects);
  drawKeypoints(image, pending->points);
  drawLabels(image, objects, dynamic_);
  drawLegend(image);
  return FrameOverlay{pending->index, image};
}

}  // namespace superdyna::system
