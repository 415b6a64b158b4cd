"""The gRPC transport of the policy service (`proto/coexist/v1/policy.proto`).

| module        | what                                                                  |
|---------------|-----------------------------------------------------------------------|
| `gen/`        | generated code (`scripts/gen_proto.sh`; committed, checked for drift) |
| `convert`     | protobuf <-> engine dataclasses                                       |
| `errors`      | the one table of error -> status code                                 |
| `servicer`    | `PolicyServicer`: Act, ActBatch, ListEnvs, Episode over the engine    |
| `server`      | `build_grpc_server`, `serve_grpc`: sync server, health, reflection    |
"""
