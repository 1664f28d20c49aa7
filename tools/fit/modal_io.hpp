// Modal parameters of an msid-model/1 document: the `modes` object written
// by `msid fit` and `msid modes`, and its printed table.
#pragma once
#include "json_util.hpp"
#include "modal.hpp"

namespace msidfit {

struct ModalReport {
    std::vector<Mode> modes;
    Domain domain = Domain::DT;
    double h = 0.0;
    bool have_sd = false;
    std::string sd_source;   // where the standard deviations come from, or why there are none
};

// Modes of a model document: with standard deviations when it holds an LMFD
// with `parameters` (names, values, cov: ml, unique lmfd), without otherwise.
ModalReport modal_report(const Json &model_doc);
Json modal_json(const ModalReport &r);
// Human-readable table (one line per mode).
std::string modal_text(const ModalReport &r);

}  // namespace msidfit
