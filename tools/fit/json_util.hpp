// Reading a JSON file with the file name in every error (fitting library).
#pragma once
#include "fit_types.hpp"
#include <nlohmann/json.hpp>

namespace msidfit {
using Json = nlohmann::ordered_json;
// Parse `path`; throws FitError ("cannot open ...", "... is not valid JSON: ...").
using msidfrf::read_json;
}  // namespace msidfit
