"""The Open Inference Protocol (KServe "v2") beside `/v1`: any v2 client (tritonclient, KServe's)
can ask coexist for an action.

| v2                                   | REST                                   | gRPC (`inference.GRPCInferenceService`) |
|--------------------------------------|----------------------------------------|-----------------------------------------|
| server live / ready                  | `GET /v2/health/live`, `/v2/health/ready` | `ServerLive`, `ServerReady`          |
| server metadata                      | `GET /v2`                              | `ServerMetadata`                        |
| model metadata / ready               | `GET /v2/models/{env}`, `.../ready`    | `ModelMetadata`, `ModelReady`           |
| infer (= `POST /v1/act`, B rows)     | `POST /v2/models/{env}/infer`          | `ModelInfer`                            |

A model is an environment (`particle`, `cooking`); its only version is "1". `core` maps a v2
request to the engine's `ActRequest` and back; `rest` and `grpc_servicer` only translate.
"""
