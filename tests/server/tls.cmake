# TLS and access tokens: what the tests need beyond mtlod_add_tests. Included by tests/CMakeLists.txt
# after the server, clients and deploy tests are defined; paths are absolute so that it does not
# matter from where.
#   mtlod_test_server_tls, mtlod_test_server_auth   tests/server/{tls,auth}_test.cpp (nothing extra)
#   mtlod_test_server_tls_proxy                     HAProxy terminating and passing TLS through
#   mtlod_test_clients_tls_tools                    the three client programs over TLS with a token
#   clients.viewer_over_https_with_a_token          the viewer in headless Chromium over https/wss
#   deploy.haproxy_config_*_tls_*                   docker/haproxy.cfg's two TLS modes, checked by HAProxy
find_program(MTLOD_OPENSSL openssl REQUIRED)

if(TARGET mtlod_test_clients_tls_tools)
  target_compile_definitions(mtlod_test_clients_tls_tools PRIVATE
                             MTLOD_CLIENT_BINARY="$<TARGET_FILE:mtlod-client>"
                             MTLOD_LOAD_BINARY="$<TARGET_FILE:mtlod-load>"
                             MTLOD_GAZE_BINARY="$<TARGET_FILE:mtlod-gaze>")
  add_dependencies(mtlod_test_clients_tls_tools mtlod-client mtlod-load mtlod-gaze)
endif()

if(MTLOD_NODE AND TARGET mtlod-server)
  add_test(NAME clients.viewer_over_https_with_a_token
           COMMAND ${MTLOD_NODE} ${PROJECT_SOURCE_DIR}/tests/clients/viewer_test.mjs --tls
                   --server $<TARGET_FILE:mtlod-server> --mesh ${MTLOD_MODELS_DIR}/bunny.ply
                   --out ${CMAKE_BINARY_DIR}/tests/clients/https)
  set_tests_properties(clients.viewer_over_https_with_a_token PROPERTIES LABELS clients SKIP_RETURN_CODE 77
                       TIMEOUT 120)
endif()

# HAProxy terminating TLS and passing it through: the same file, its TLS modes chosen by MTLOD_TLS,
# with a certificate made at test time (HAProxy finds its key beside it as <file>.key).
if(MTLOD_HAPROXY)
  set(tls_pem ${CMAKE_BINARY_DIR}/tests/haproxy-tls.pem)
  add_test(NAME deploy.haproxy_tls_certificate
           COMMAND ${MTLOD_OPENSSL} req -x509 -newkey rsa:2048 -nodes -days 2 -subj /CN=127.0.0.1
                   -addext subjectAltName=IP:127.0.0.1 -keyout ${tls_pem}.key -out ${tls_pem})
  set_tests_properties(deploy.haproxy_tls_certificate PROPERTIES LABELS deploy FIXTURES_SETUP haproxy_tls_pem)
  foreach(mode terminate passthrough)
    mtlod_add_cli_test(deploy.haproxy_config_with_tls_${mode}_is_valid STATUS 0 MATCH "Configuration file is valid"
                       COMMAND ${MTLOD_HAPROXY} -c -f ${PROJECT_SOURCE_DIR}/docker/haproxy.cfg)
    set_tests_properties(deploy.haproxy_config_with_tls_${mode}_is_valid PROPERTIES LABELS deploy
                         FIXTURES_REQUIRED haproxy_tls_pem
                         ENVIRONMENT "${haproxy_environment};MTLOD_TLS=${mode};MTLOD_TLS_CERT=${tls_pem}")
  endforeach()
endif()

# docker/haproxy.cfg's TLS layouts run end to end (tests/server/tls_proxy_test.cpp).
if(TARGET mtlod_test_server_tls_proxy AND MTLOD_HAPROXY)
  target_compile_definitions(mtlod_test_server_tls_proxy PRIVATE MTLOD_HAPROXY_BINARY="${MTLOD_HAPROXY}")
endif()
