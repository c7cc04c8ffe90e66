// Detection of coplanar overlapping planar faces (box faces, caps, half-space
// planes) between primitives of one CSG object. Such configurations are
// resolved by the rule in csg.h, but [Thesis §4.1.2] notes they usually
// come from careless modelling, so they are reported as warnings.
#pragma once

#include <string>
#include <vector>

#include "csg/primitive.h"

namespace plm::csg {

// One message per pair of primitives (both used by the tree) with planar
// faces in the same plane (within tol, either orientation) that overlap in an
// area, not just along an edge.
std::vector<std::string> find_coplanar_faces(const std::string& object, const std::vector<Primitive>& prims,
                                             const std::vector<bool>& used, double tol);

}  // namespace plm::csg
