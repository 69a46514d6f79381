// shadow.hpp - cast shadows against a captured colour background: darker by a roughly constant ratio in every
// channel, the background's chromaticity and texture kept, so table in shade rather than an object.
#pragma once
#include <opencv2/core.hpp>

#include "background.hpp"
#include "components.hpp"

namespace rbx1::vision {

struct ShadowOptions {
  double min_ratio = 0.35;    // shade darkens the table to between these fractions of its light...
  double max_ratio = 0.92;
  double max_spread = 0.05;   // ...alike in every channel: each channel's ratio within this of the mean ratio
                              // (plus the noise's share, 8 levels over the channel's background level)
  double min_chroma = 30;     // applied only on a coloured background: its median chroma (max - min channel,
                              // on the smoothed background) at least this many levels; on grey, any grey
                              // object darker than the table would pass as shade
};

// On a grey table the ratio cannot tell a dark grey object from shade; what can: shade is bounded by soft
// edges (its penumbra) on its table side and is attached to a darker object that casts it, across that
// object's sharp edge, while an object is bounded by sharp edges all round.
struct GreyShadeOptions {
  double min_ratio = 0.35;     // shade darkens the table to at least this fraction of its light...
  double min_depth = 4;        // ...and by at least this many levels: its penumbra included
  double sharp_slope = 0.32;   // an edge is sharp where the grey slope (levels/px) exceeds this fraction of
                               // the grey range over 7x7 around it: a blurred step of sigma <= 1.1 px peaks
                               // above 0.36, a penumbra of sigma >= 1.5 px below 0.27
  double min_penumbra_px = 1.8; // ...through a penumbra: its 25-75 % band this wide on average (a blurred object
                               // edge of sigma <= 1.1 px is under 1.5 px; a shadow's of sigma >= 1.5 px over 2)
  double min_soft = 0.1;       // shade: at least this fraction of its outline borders the lit table directly
  double caster_margin = 0.08; // ...and beyond its sharp edges lies an object darker by this much of the table
  int min_area_px = 20;        // smaller candidate pieces are left as they are
};

// The table in shade on a grey table: gray, background: CV_8U, same size (the background already in the
// scene's light). Returns the number of shade pixels; when there are any, `mask` (CV_8U, 255 = shade) and
// `shaded`, the background in the scene's shade (CV_8U: on shade pixels the frame's grey, within 2 px of them
// the caster's coverage, the background elsewhere); both empty when there are none. The work is done only in
// the boxes of the regions darker than the table.
// also (optional): a second labelling of the dark polarity (the isolation's, at its own levels) made in the same
// streamed pass as the shade's own candidates; left untouched (its labels empty) when the images are not 8-bit
// of one size.
int grey_shade_mask(const cv::Mat& gray, const cv::Mat& background, const GreyShadeOptions& opt, cv::Mat& mask,
                    cv::Mat& shaded, Labelling* also = nullptr);

// true when the background's median chroma reaches opt.min_chroma (the colour shadow test applies).
bool coloured_background(const cv::Mat& background_bgr, const ShadowOptions& opt);

// frame, background: CV_8UC3 (BGR), same size; light: the change fitted between them on grey
// (compensate_light), applied to the background first. Returns the number of shadow pixels and `mask`
// (CV_8U, 255 = shade; 3x3 opened: isolated pixels and 1-2 px rims are not shade); 0 and an all-zero mask when
// the background is not coloured enough or the images are not 8-bit BGR.
int shadow_mask(const cv::Mat& frame, const cv::Mat& background, const LightFit& light, const ShadowOptions& opt,
                cv::Mat& mask);

}  // namespace rbx1::vision
