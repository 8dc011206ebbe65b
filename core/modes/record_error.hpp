#pragma once
// A mode's file that cannot be read: malformed, of another schema, or with a value out of place.
// The message names the file.
#include <stdexcept>

namespace calbox::modes {

class RecordError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

}  // namespace calbox::modes
