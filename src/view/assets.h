#pragma once
// The page and its script, built into the library from viewer/ (cmake/EmbedFiles.cmake writes
// the definitions of the two raw accessors from viewer/index.html and viewer/dist/viewer.js).

#include <string>
#include <string_view>

#include "chronomap/core/base64.h"

namespace chronomap::viewer_assets {

/// viewer/index.html as committed (generated source).
std::string_view pageTemplate();
/// viewer/dist/viewer.js as committed (generated source).
std::string_view viewerScript();

/// The page with its <!--CHRONOMAP_SCRIPT--> and <!--CHRONOMAP_DATA--> marks replaced.
std::string page(const std::string& script, const std::string& data);
/// <script src="URL"></script>
std::string scriptTag(const std::string& url);
/// The script inside a <script> element, with "</script" and "<!--" escaped.
std::string inlineScript(std::string_view script);
/// `bytes` base64-encoded inside <script type="application/octet-stream" id="chronomap-data">.
std::string inlineData(const std::string& bytes);
/// Standard base64 with padding (core/base64.h).
using chronomap::base64;

}  // namespace chronomap::viewer_assets
