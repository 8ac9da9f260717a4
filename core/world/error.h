// The one exception type of the core API. Every check of user input throws
// it with a message that names the object and the bad value; the world is
// left as it was before the call.
#pragma once

#include <stdexcept>
#include <string>

namespace blockstep {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error("blockstep: " + what) {}
};

}  // namespace blockstep
