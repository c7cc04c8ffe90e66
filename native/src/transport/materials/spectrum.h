// Wavelengths for dispersion (thesis appendix A.1.2): a photon that meets a
// dispersive lobe becomes one wavelength, drawn uniformly over 380-780 nm,
// and its RGB flux is weighted by rgb_weight(lambda): the CIE 1931 colour
// matching functions [Wyman13] taken to linear sRGB (D65), negative parts
// cut, each channel scaled so that its mean over the range is 1. White light
// split into wavelengths then sums back to white, and an RGB flux keeps its
// expected value.
#pragma once

#include "util/math.h"

namespace plm {

constexpr float kLambdaMinNm = 380.0f, kLambdaMaxNm = 780.0f;

// The weight of wavelength lambda (nm) in linear sRGB; 0 outside the range.
Vec3 rgb_weight(float lambda_nm);

// The CIE 1931 2-degree colour matching functions (x, y, z) at lambda (nm),
// the multi-lobe Gaussian fit of [Wyman13].
Vec3 cie_xyz(float lambda_nm);

}  // namespace plm
