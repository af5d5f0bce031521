// The web page served at "/": lists jobs with live progress, shows a finished sweep's saturation
// map and FRF families (SVG rendered by the server). Compiled in from server/web/index.html.
#pragma once

#include <string>

namespace strokelab::server {

const std::string& WebPage();

}  // namespace strokelab::server
