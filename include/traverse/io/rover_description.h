// rover.urdf → RoverGeometry (urdfdom). The joint ↔ joints.csv column map comes from
// rover.yaml (RoverConfig::joint_names); a URDF mimic joint (the rocker differential) follows
// the joint it mimics.
#pragma once

#include <filesystem>
#include <string>

#include "traverse/io/rover_config.h"
#include "traverse/rover/rover_geometry.h"

namespace traverse::io {

/// Reads and checks a rover URDF. Errors are InputErrors naming the file and the joint/link.
rover::RoverGeometry loadRoverGeometry(const std::filesystem::path& urdf_file,
                                       const RoverConfig& config);

/// Same, from URDF text (`source` names it in error messages).
rover::RoverGeometry parseRoverGeometry(const std::string& urdf_xml, const RoverConfig& config,
                                        const std::string& source);

}  // namespace traverse::io
