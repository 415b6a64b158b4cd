"""The serving side: the inference engine (`services.engine`) and its two thin transports, REST
(`services.rest`, FastAPI) and gRPC (`services.grpc_api`), the registry HTTP API
(`services.registry`), the trainer job API (`services.jobs_api`), the app that assembles them
(`services.app`), and the clients (`coexist_client`, `services.env_client`)."""
