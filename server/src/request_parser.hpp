// request_parser.hpp — the HTTP/1 request parser of a session. Private to the server.
//
// Beast's HTTP/1 request grammar and limits (basic_parser: header_limit, body_limit, chunked
// decoding), with the fields the handler reads stored straight into the session's Request: no
// field container and no allocation per field. The body goes to Request::body, or to the upload
// file once write_body_to() has named one. Repeated fields: the first one counts (Host: counted).
#pragma once

#include <boost/beast/core/file.hpp>
#include <boost/beast/core/string.hpp>
#include <boost/beast/http/basic_parser.hpp>
#include <boost/beast/http/field.hpp>
#include <cstdint>

#include "tinstream/server/http_types.hpp"

namespace tinstream::server {

namespace beast = boost::beast;
namespace http = boost::beast::http;

class RequestParser final : public http::basic_parser<true> {
 public:
  explicit RequestParser(Request& request) : req_(request) {}

  unsigned version() const { return version_; }
  bool expect_continue() const { return expect_continue_; }
  unsigned host_fields() const { return hosts_; }
  std::uint64_t body_bytes() const { return body_bytes_; }
  void write_body_to(beast::file& file) { file_ = &file; }

 private:
  void on_request_impl(http::verb, beast::string_view method, beast::string_view target,
                       int version, beast::error_code&) override {
    req_.method.assign(method.data(), method.size());
    req_.target.assign(target.data(), target.size());
    version_ = static_cast<unsigned>(version);
  }
  void on_response_impl(int, beast::string_view, int, beast::error_code&) override {}

  void on_field_impl(http::field name, beast::string_view, beast::string_view value,
                     beast::error_code&) override {
    const auto first = [&](std::string& out, unsigned bit) {
      if (seen_ & bit) return;
      seen_ |= bit;
      out.assign(value.data(), value.size());
    };
    switch (name) {
      case http::field::accept:
        return first(req_.accept, 1u);
      case http::field::accept_encoding:
        return first(req_.accept_encoding, 2u);
      case http::field::if_none_match:
        return first(req_.if_none_match, 4u);
      case http::field::authorization:
        return first(req_.authorization, 8u);
      case http::field::content_type:
        return first(req_.content_type, 16u);
      case http::field::host:
        ++hosts_;
        return;
      case http::field::expect:
        if (seen_ & 32u) return;
        seen_ |= 32u;
        expect_continue_ = beast::iequals(value, "100-continue");
        return;
      default:
        return;
    }
  }
  void on_header_impl(beast::error_code&) override {}

  void on_body_init_impl(const boost::optional<std::uint64_t>& length,
                         beast::error_code&) override {
    if (!file_ && length) req_.body.reserve(static_cast<std::size_t>(*length));
  }
  std::size_t on_body_impl(beast::string_view body, beast::error_code& ec) override {
    if (file_) {
      file_->write(body.data(), body.size(), ec);
    } else {
      req_.body.append(body.data(), body.size());
    }
    body_bytes_ += body.size();
    return body.size();
  }
  void on_chunk_header_impl(std::uint64_t, beast::string_view, beast::error_code&) override {}
  std::size_t on_chunk_body_impl(std::uint64_t, beast::string_view body,
                                 beast::error_code& ec) override {
    return on_body_impl(body, ec);
  }
  void on_finish_impl(beast::error_code&) override {}

  Request& req_;
  beast::file* file_ = nullptr;
  std::uint64_t body_bytes_ = 0;
  unsigned version_ = 11;
  unsigned seen_ = 0;   // bits of the fields already stored
  unsigned hosts_ = 0;  // Host field lines
  bool expect_continue_ = false;
};

}  // namespace tinstream::server
