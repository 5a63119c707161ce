#pragma once
// The configuration of the online commands (`sonar3d ros`, `sonar3d online`), each part from its
// one declaration: the carving (ReconstructConfig, as `sonar3d reconstruct`), the recognition
// used with --catalogue (RecognizeConfig, as `sonar3d recognize`) and how often it runs
// (OnlineRecognitionConfig). --print-config prints the three blocks; --config reads any of them
// (a file `sonar3d reconstruct --print-config` or `sonar3d recognize --print-config` wrote works
// as it is). A flag both declare (--method, --threads, --map-cell) sets the carving's; the
// recognition's is set in the file.
#include <cstring>
#include <string>

#include "commands.hpp"
#include "sonar3d/pipeline/online_recognition.hpp"
#include "sonar3d/recog/recognize.hpp"
#include "sonar3d/recon/reconstruct.hpp"

namespace sonar3d::cli {

struct OnlineNodeConfig {
  ReconstructConfig reconstruct;
  RecognizeConfig recognize;
  OnlineRecognitionConfig online_recognition;
};
template <class V>
void describe(OnlineNodeConfig& c, V& v) {
  v.group("reconstruct", c.reconstruct);
  v.group("recognize", c.recognize);
  v.group("online_recognition", c.online_recognition);
}

// Library errors name fields by their path within their own config ("voxel_size"): the flag
// names without the group.
inline FlagNames online_node_flag_names(FlagNames flags) {
  for (auto& [path, flag] : flags) {
    for (const char* group : {"reconstruct.", "recognize.", "online_recognition."}) {
      if (path.rfind(group, 0) == 0) path = path.substr(std::strlen(group));
    }
  }
  return flags;
}

}  // namespace sonar3d::cli
