#pragma once
/// \file distance.hpp
/// The closest-point routines of detection live in framework/distance.hpp since the rod
/// generator checks the rest shapes it seeds with them (framework cannot include contact).
/// Detection keeps its names.
#include "framework/distance.hpp"

namespace weft::contact::detection {

using weft::PointSegment;
using weft::PointTriangle;
using weft::SegmentSegment;
using weft::point_segment_distance;
using weft::point_triangle_distance;
using weft::segment_segment_distance;

}  // namespace weft::contact::detection
